"""The page's composited rate judges the display rate (raspv_spv/page_presentation.py): a page
that composites 57.6 of 90 frames/s refuses 90 Hz with the reason; one at 87 keeps it; reports
across a rate change are not mixed; a page whose refresh is below the rate is asked for its
refresh; a verdict is announced only when it changes."""
from __future__ import annotations

import pytest

from raspv_spv.page_presentation import MARGIN_FPS, SETTLE_S, WINDOW_S, PagePresentation


def feed(p: PagePresentation, fps, rate: float, start: float, seconds: float, refresh: float | None = 90.0):
    """One report a second; the announced verdicts."""
    said = []
    t = start
    while t < start + seconds:
        v = p.add(fps(t) if callable(fps) else fps, refresh, rate, t)
        if v is not None:
            said.append(v)
        t += 1.0
    return said


def test_a_page_below_the_rate_refuses_it_with_the_reason_and_one_that_keeps_it_is_ok():
    p = PagePresentation()
    said = feed(p, 57.6, 90.0, 0.0, 20.0)
    assert len(said) == 1 and not said[0].kept                    # announced once, not every second
    assert said[0].presented_fps == pytest.approx(57.6) and said[0].asked_fps == 90.0
    reason = said[0].reason
    assert "57.6 of 90 frames/s" in reason and "90 Hz is not kept" in reason
    status = p.status(20.0)["90"]
    assert status["verdict"] == "refused" and status["reason"] == reason
    said = feed(p, 87.0, 90.0, 20.0, 20.0)                        # the load went away: kept again, once
    assert [v.kept for v in said] == [True]
    assert p.status(40.0)["90"]["verdict"] == "ok" and "reason" not in p.status(40.0)["90"]


def test_the_margin_is_five_frames_below_the_asked_rate():
    for fps, kept in ((90.0 - MARGIN_FPS, True), (90.0 - MARGIN_FPS - 0.5, False)):
        p = PagePresentation()
        assert [v.kept for v in feed(p, fps, 90.0, 0.0, WINDOW_S + SETTLE_S + 1)] == [kept]


def test_no_verdict_before_enough_reports_at_the_new_rate():
    p = PagePresentation()
    assert feed(p, 88.0, 90.0, 0.0, 4.0) == []                     # 4 reports: too few
    feed(p, 88.0, 90.0, 4.0, 20.0)
    # the rate changes to 50: the page's first seconds at 50 are not judged with the 90 Hz reports
    said = feed(p, lambda t: 88.0 if t < 25.0 else 49.0, 50.0, 24.0, 20.0)
    assert [(v.rate_hz, v.kept) for v in said] == [(50.0, True)]
    assert set(p.status(44.0)) == {"50", "90"}                     # 90 Hz's verdict is kept after the change


def test_a_page_whose_refresh_is_below_the_rate_is_asked_for_its_refresh():
    p = PagePresentation()
    said = feed(p, 59.5, 90.0, 0.0, 15.0, refresh=60.0)
    assert said[0].kept and said[0].asked_fps == 60.0
    p = PagePresentation()
    said = feed(p, 59.5, 90.0, 0.0, 15.0, refresh=None)            # the browser's frame callback: asked the rate
    assert not said[0].kept and "browser's frame callback" in said[0].reason


def test_a_report_no_page_can_make_is_an_error():
    p = PagePresentation()
    with pytest.raises(ValueError, match="fps"):
        p.add(-3.0, 90.0, 90.0, 0.0)
    with pytest.raises(ValueError, match="refresh"):
        p.add(60.0, -90.0, 90.0, 0.0)

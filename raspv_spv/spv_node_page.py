"""The wearer's page in the spv node's display budget (ROS side of
:mod:`raspv_spv.page_presentation`): the bridge forwards what the controlling page composited
(``/hmd/presentation``, ~1 Hz); the node judges its display rate by it and puts the verdict per
rate into ``/spv/status`` (``display.page``; a rate the page did not keep is ``refused`` in
``display.rates`` with the reason), logging one warning when a rate is refused and one line when
it is kept again. A mixin of :class:`raspv_spv.spv_node.SpvNode`.
"""
from __future__ import annotations

import copy
import json
import time
from typing import Any

from std_msgs.msg import String

from raspv_common import topics
from raspv_common.qos import EVENT_QOS
from raspv_spv.page_presentation import PagePresentation

RETRY_S = 60.0     # a rate the page did not keep is refused by `param set` for this long [s]


class SpvPage:
    """The page's composited rate → the display budget's verdict (see the module docstring)."""

    def _setup_page(self) -> None:
        self.page = PagePresentation()
        self.create_subscription(String, topics.HMD_PRESENTATION, self.on_presentation, EVENT_QOS)

    def on_presentation(self, msg: String) -> None:
        try:
            report = json.loads(msg.data)
            fps, refresh = float(report["fps"]), report.get("refresh_hz")
            verdict = self.page.add(fps, None if refresh is None else float(refresh), float(self.params["rate"]),
                                    time.monotonic())
        except (json.JSONDecodeError, KeyError, TypeError, ValueError) as exc:
            self.warn_throttled("presentation", f"ignoring {topics.HMD_PRESENTATION}: {exc}")
            return
        if verdict is None:
            return
        if verdict.kept:
            self.get_logger().info(f"the page keeps {verdict.rate_hz:g} Hz: {verdict.presented_fps:.1f} frames/s composited")
        else:
            self.get_logger().warning(verdict.reason)
        args = getattr(self, "_status_args", None)
        if args is not None:
            self._publish_status(*args)

    def page_refusal(self, rate_hz: float) -> str | None:
        """Why ``rate_hz`` is refused when the page did not keep it in the last ``RETRY_S``, else None."""
        verdict = self.page.verdicts.get(rate_hz)
        if verdict is None or verdict.kept:
            return None
        age = time.monotonic() - verdict.measured_at
        if age >= RETRY_S:
            return None
        return f"{verdict.reason} (measured {age:.0f} s ago; it may be tried again {RETRY_S - age:.0f} s from now)"

    def display_status(self) -> dict[str, Any] | None:
        """``display_budget.rate_costs`` with the page's verdicts: ``page`` per rate, and a rate the
        page did not keep refused in ``rates`` (and at the top when it is the node's rate)."""
        costs = getattr(self, "display_costs", None)
        page = getattr(self, "page", None)
        if costs is None or page is None or not page.verdicts:
            return costs
        out = copy.deepcopy(costs)
        out["page"] = page.status(time.monotonic())
        for rate, verdict in page.verdicts.items():
            if verdict.kept:
                continue
            entry = out["rates"].setdefault(f"{rate:g}", {})
            entry.update(verdict="refused", reason=verdict.reason)
            if rate == out.get("rate_hz"):
                out.update(verdict="refused", reason=verdict.reason)
        return out

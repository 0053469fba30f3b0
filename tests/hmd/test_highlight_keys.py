"""Headset keys for the highlight overlay: t / T cycle the highlighted class, y turns it on/off."""
import pytest

from raspv_hmd.keymap import HIGHLIGHT_CLASSES, key_change, parameters_needed


def test_t_and_shift_t_cycle_the_highlighted_class():
    assert parameters_needed("t") == ["highlight.classes"]
    change = key_change("t", {"highlight.classes": ["person"]}, [])
    assert (change.name, change.value) == ("highlight.classes", [HIGHLIGHT_CLASSES[1]])
    back = key_change("T", {"highlight.classes": [HIGHLIGHT_CLASSES[0]]}, [])
    assert back.value == [HIGHLIGHT_CLASSES[-1]]                        # wraps around
    assert key_change("t", {"highlight.classes": ["giraffe"]}, []).value == [HIGHLIGHT_CLASSES[0]]
    assert key_change("t", {"highlight.classes": []}, []).value == [HIGHLIGHT_CLASSES[0]]


def test_y_toggles_the_highlight_overlay_and_keeps_the_others():
    on = key_change("y", {"overlays": ["path"]}, [])
    assert on.value == ["path", "highlight"] and on.text == "highlight on"
    assert key_change("y", {"overlays": ["path", "highlight"]}, []).value == ["path"]


def test_highlight_keys_on_an_spv_node_without_the_parameter_say_so():
    with pytest.raises(ValueError, match="no parameter 'highlight.classes'"):
        key_change("t", {"highlight.classes": None}, [])

import pytest

from raspv_common.params import Param, ParamSchema

SCHEMA = ParamSchema.of([
    Param("fov", 20.0, "field of view", minimum=1.0, maximum=180.0),
    Param("n", 1000, "phosphenes", minimum=1, maximum=10000),
    Param("grid", "hexagonal", "lattice", choices=("hexagonal", "rectangular")),
    Param("temporal", True, "temporal model"),
    Param("overlays", ["stairs"], "overlays"),
    Param("tags", [], "free tags"),
])


def test_valid_values_are_coerced():
    good, errors = SCHEMA.validate({"fov": 30, "n": 5, "grid": "rectangular", "temporal": False, "tags": ["a"]})
    assert errors == []
    assert good["fov"] == 30.0 and isinstance(good["fov"], float)
    assert good["tags"] == ["a"]


@pytest.mark.parametrize("key,value,fragment", [
    ("fov", 500.0, "out of range"),
    ("fov", "wide", "expected float"),
    ("fov", float("nan"), "finite"),
    ("n", 2.5, "expected int"),
    ("n", True, "expected int"),
    ("grid", "triangular", "one of 'hexagonal', 'rectangular'"),
    ("temporal", "yes", "expected bool"),
    ("overlays", "stairs", "expected list of string"),
    ("overlays", [1], "expected string"),
    ("colour", 1, "unknown parameter; this node has: fov, grid, n, overlays, tags, temporal"),
])
def test_bad_values_name_what_is_allowed(key, value, fragment):
    good, errors = SCHEMA.validate({key: value})
    assert key not in good
    assert len(errors) == 1 and errors[0][0] == key
    assert fragment in errors[0][1]


def test_schema_rejects_duplicates_and_bad_defaults():
    with pytest.raises(ValueError):
        ParamSchema.of([Param("a", 1, ""), Param("a", 2, "")])
    with pytest.raises(ValueError):
        ParamSchema.of([Param("a", 5, "", maximum=3)])


def test_parameters_that_only_work_together():
    schema = ParamSchema.of([
        Param("cert", "", "certificate", needs=("key",)),
        Param("key", "", "its key", needs=("cert",)),
        Param("mode", "build", "mode", choices=("build", "follow"), needs=("map",), needs_when=("follow",)),
        Param("map", "", "map file", excludes=("world",)),
        Param("world", "", "world"),
    ])
    assert schema.check_together({}) == []
    assert schema.check_together({"cert": "c", "key": "k", "mode": "follow", "map": "m"}) == []
    assert schema.check_together({"key": "k"}) == [
        ("key", "set without cert: key and cert only work together (set both or neither)")]
    assert schema.check_together({"mode": "follow"}) == [("mode", "'follow' needs map, which is not set")]
    assert schema.check_together({"map": "m", "world": "w"}) == [("map", "map and world are both set: give one of them")]
    assert schema["mode"].pairing() == "needs map when 'follow'" and schema["map"].pairing() == "not with world"
    with pytest.raises(ValueError, match="unknown nope"):
        ParamSchema.of([Param("a", "", "", needs=("nope",))])

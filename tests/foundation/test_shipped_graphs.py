"""Every graph shipped in config/ validates against the node schemas."""
import pytest

from raspv_bringup.graph import CONFIG_DIR, load_graph

GRAPHS = sorted(p for p in CONFIG_DIR.glob("*.yaml"))


def test_graphs_are_shipped():
    assert {p.stem for p in GRAPHS} >= {"demo", "navigation", "replay"}


@pytest.mark.parametrize("path", GRAPHS, ids=[p.stem for p in GRAPHS])
def test_shipped_graph_validates(path):
    graph = load_graph(path)
    assert graph.nodes

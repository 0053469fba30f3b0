"""The claims file (issue 33): every performance claim of docs/speed.md is in docs/claims.yaml with
every number of its row, the command that prints it, and the test that gates it (or why none
can); every gate names a test that exists and ratios that have floors. A figure changed in the
speed table without its claim fails here, so the change comes with a look at its gate."""
from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from raspv_bench.bench_cli import BENCHES
from raspv_bench.ratios import CLAIMS, GATED, load_floors
from raspv_bringup.cli import COMMANDS

ROOT = Path(__file__).resolve().parents[2]
SPEED = ROOT / "docs" / "speed.md"
# thousands written with a space, thin space or comma ("2 500", "32,640") are one number
THOUSANDS = re.compile(r"(?<=\d)[ ,\u2009\u202f\u00a0](?=\d{3}(?!\d))")
NUMBER = re.compile(r"\d+(?:\.\d+)?(?:e[-+]?\d+)?")


def numbers(text: str) -> set[str]:
    return set(NUMBER.findall(THOUSANDS.sub("", text)))


def speed_rows() -> dict[str, dict[str, str]]:
    """The speed table's rows by id: {id: {what, bench, target, measured, conditions}}."""
    rows = {}
    for line in SPEED.read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if not line.startswith("| ") or len(cells) != 6 or cells[0] in ("id", "") or set(cells[0]) <= {"-"}:
            continue
        rows[cells[0]] = dict(zip(("what", "bench", "target", "measured", "conditions"), cells[1:]))
    return rows


CLAIMED = yaml.safe_load(CLAIMS.read_text(encoding="utf-8"))["claims"]
ROWS = speed_rows()
FLOORS = load_floors()


def test_the_speed_table_is_read_and_every_row_has_exactly_one_claim():
    assert len(ROWS) >= 40, "docs/speed.md's table was not found or changed its columns"
    assert sorted(set(ROWS) - set(CLAIMED)) == [], "rows of docs/speed.md without a claim in docs/claims.yaml"
    assert sorted(set(CLAIMED) - set(ROWS)) == [], "claims in docs/claims.yaml whose row left docs/speed.md"


@pytest.mark.parametrize("row_id", sorted(ROWS))
def test_every_number_of_a_row_is_in_its_claim(row_id):
    row, claim = ROWS[row_id], CLAIMED.get(row_id) or {}
    text = " ".join(row[k] for k in ("what", "target", "measured", "conditions"))
    missing = sorted(numbers(text) - numbers(str(claim.get("claim", ""))))
    assert not missing, (f"docs/speed.md row {row_id}: {missing} not in its claim in docs/claims.yaml — "
                         "update the claim and look at its gate")


def _bench_exists(bench: str) -> bool:
    words = bench.split()
    if words[:2] == ["raspv", "bench"]:
        return len(words) > 2 and words[2] in BENCHES
    if words[:1] == ["raspv"]:
        return len(words) > 1 and words[1] in COMMANDS
    if bench.startswith("tests/"):
        return (ROOT / words[0]).is_file()
    return False


def _test_exists(node: str) -> bool:
    path, _, name = node.partition("::")
    file = ROOT / path
    return file.is_file() and re.search(rf"^def {re.escape(name)}\(", file.read_text(encoding="utf-8"), re.M) is not None


@pytest.mark.parametrize("claim_id", sorted(CLAIMED))
def test_every_claim_names_its_bench_and_a_gate_or_why_not(claim_id):
    claim = CLAIMED[claim_id]
    bench = str(claim.get("bench", ""))
    table = ROWS.get(claim_id, {}).get("bench", "").strip("`")
    if bench == "none":
        assert table == "—" and claim.get("not_gated"), f"{claim_id}: no bench only where the table names none"
    else:
        assert _bench_exists(bench), f"{claim_id}: {bench!r} is not a raspv command, bench or test file here"
        if table not in ("—", ""):
            assert bench.removeprefix("raspv ").startswith(table), f"{claim_id}: the table says {table!r}"
    gate, why = claim.get("gate"), claim.get("not_gated")
    assert bool(gate) != bool(why), f"{claim_id}: a gate or a reason why not, one of the two"
    if gate:
        assert _test_exists(gate["test"]), f"{claim_id}: no test {gate['test']}"
        for ratio in gate.get("ratios", []):
            assert ratio in FLOORS, f"{claim_id}: ratio {ratio} has no floor in docs/claims.yaml"


def test_every_gated_ratio_stands_for_a_claim_and_states_its_margin():
    cited = {r for c in CLAIMED.values() if c.get("gate") for r in c["gate"].get("ratios", [])}
    assert set(FLOORS) <= cited, f"ratios with a floor that no claim cites: {sorted(set(FLOORS) - cited)}"
    for key, spec in FLOORS.items():
        assert key.partition(".")[0] in GATED, f"{key}: its bench is not run by the gate"
        assert float(spec["floor"]) > 0 and len(str(spec.get("margin", ""))) > 40, f"{key}: a floor and its margin"


# claims found without a check (issue 33), withdrawn: they must not come back on the pages people read
WITHDRAWN = {"bit-identical": "scene perception's equivalence to its previous code: no test keeps it",
             "× the paper's": "a ratio against another network's published time on another machine",
             "same results)": "scene perception's equivalence to its previous code: no test keeps it",
             "reproduces the study's rise": "the count sweep improves only below the study's range (docs/experiments.md)"}
READ_PAGES = ("README.md", "docs/speed.md", "docs/perception.md", "docs/cameras.md", "docs/index.md", "docs/spv.md")


def test_withdrawn_claims_stay_withdrawn():
    for page in READ_PAGES:
        text = (ROOT / page).read_text(encoding="utf-8")
        for phrase, why in WITHDRAWN.items():
            assert phrase not in text, f"{page} says {phrase!r}: {why}"


def test_the_gaze_row_is_the_quiet_measurement_of_its_docs_page():
    """docs/spv.md's latency paragraph has the latest quiet measurement: the speed row states it."""
    spv = " ".join((ROOT / "docs" / "spv.md").read_text(encoding="utf-8").split())
    found = re.search(r"gaze steps onset p50 \*\*([\d.]+) ms, p95 ([\d.]+) ms\*\*", spv)
    assert found, "docs/spv.md no longer states the gaze steps' quiet onset"
    row = ROWS["e2e-gaze-step"]
    assert f"p50 {found[1]} ms, p95 {found[2]} ms" in row["measured"] and row["conditions"].startswith("quiet")
    assert "not met" not in row["measured"] and float(found[2]) <= 25.0      # the row's target: onset p95 ≤ 25 ms

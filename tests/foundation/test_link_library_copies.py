"""tools/link_library_copies.py: the identical copies of a versioned shared library become links
to the most versioned one; a different file of the same stem and other files are left alone."""
import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
spec = importlib.util.spec_from_file_location("link_library_copies", ROOT / "tools/link_library_copies.py")
tool = importlib.util.module_from_spec(spec)
spec.loader.exec_module(tool)


def test_identical_copies_become_links_and_the_rest_stays(tmp_path):
    body = bytes(range(256)) * 40
    for name in ("libdds.so", "libdds.so.2", "libdds.so.2.14.5"):
        (tmp_path / name).write_bytes(body)
    (tmp_path / "libother.so").write_bytes(body)
    (tmp_path / "libother.so.1").write_bytes(body[:-1] + b"x")     # same size, other bytes
    (tmp_path / "notes.so.txt").write_bytes(body)
    assert tool.link_copies(tmp_path) == 2 * len(body)
    assert (tmp_path / "libdds.so").readlink() == Path("libdds.so.2.14.5")
    assert (tmp_path / "libdds.so.2").readlink() == Path("libdds.so.2.14.5")
    assert (tmp_path / "libdds.so").read_bytes() == body and not (tmp_path / "libdds.so.2.14.5").is_symlink()
    assert not any(p.is_symlink() for p in tmp_path.glob("libother*"))
    assert tool.link_copies(tmp_path) == 0                                 # a second run changes nothing


def test_the_installed_venv_has_no_library_copies_left():
    lib = ROOT / ".venv" / "lib"
    if not (lib / "libfastrtps.so").exists():
        import pytest
        pytest.skip("no venv built by tools/install.sh here")
    assert (lib / "libfastrtps.so").is_symlink()

"""Plain-file doors of geoblock.io: atomic writes and reads that name the file."""

from __future__ import annotations

import json

import pytest

from geoblock.errors import GeoblockIOError, MetadataFieldError
from geoblock.io import files


def test_round_trips(tmp_path):
    files.write_text(tmp_path / "a.md", "# é\n")
    assert files.read_text(tmp_path / "a.md") == "# é\n"
    files.write_json(tmp_path / "a.json", {"x": [1, 2]})
    assert files.read_json(tmp_path / "a.json") == {"x": [1, 2]}
    (tmp_path / "a.toml").write_text('x = 1\n[t]\ny = "z"\n')
    assert files.read_toml(tmp_path / "a.toml") == {"x": 1, "t": {"y": "z"}}
    files.write_csv(tmp_path / "a.csv", [{"id": "p1", "v": 1.5}, {"id": "p2", "v": 2}])
    assert (tmp_path / "a.csv").read_text() == "id,v\np1,1.5\np2,2\n"
    files.write_csv(tmp_path / "b.csv", [[1, 2]], header=["a", "b"])
    assert (tmp_path / "b.csv").read_text() == "a,b\n1,2\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "a.csv", "a.json", "a.md", "a.toml", "b.csv"]  # no temporaries left


def test_errors_name_the_file(tmp_path):
    with pytest.raises(GeoblockIOError, match="missing.toml"):
        files.read_toml(tmp_path / "missing.toml")
    (tmp_path / "bad.toml").write_text("x = = 1\n")
    with pytest.raises(MetadataFieldError, match=r"bad.toml: TOML: not valid TOML"):
        files.read_toml(tmp_path / "bad.toml")
    (tmp_path / "latin1.txt").write_bytes("é".encode("latin-1"))
    with pytest.raises(GeoblockIOError, match=r"latin1.txt: not UTF-8"):
        files.read_text(tmp_path / "latin1.txt")
    with pytest.raises(GeoblockIOError, match=r"no-such-dir"):
        files.write_text(tmp_path / "no-such-dir" / "x.txt", "x")
    with pytest.raises(GeoblockIOError, match=r"not JSON-safe"):
        files.write_json(tmp_path / "nan.json", {"x": float("nan")})
    assert not (tmp_path / "nan.json").exists()


def test_a_failed_write_keeps_the_previous_file(tmp_path):
    target = tmp_path / "keep.json"
    files.write_json(target, {"v": 1})

    def boom(f):
        f.write(b"half")
        raise RuntimeError("interrupted")

    with pytest.raises(RuntimeError):
        files.write_with(target, boom)
    assert json.loads(target.read_text()) == {"v": 1}
    assert [p.name for p in tmp_path.iterdir()] == ["keep.json"]


def test_atomic_directory_and_figures(tmp_path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = tmp_path / "out"
    with files.atomic_directory(out) as tmp:
        fig, ax = plt.subplots()
        ax.plot([0, 1])
        files.save_figure(fig, tmp / "f.png", dpi=50)
        plt.close(fig)
        files.make_directory(tmp / "models")
    assert (out / "f.png").read_bytes()[:4] == b"\x89PNG" and (out / "models").is_dir()


def test_remove_files_links_and_trees_but_not_link_targets(tmp_path):
    target = tmp_path / "target"
    target.mkdir()
    (target / "keep.txt").write_text("x")
    link = tmp_path / "link"
    link.symlink_to(target)
    tree = tmp_path / "tree" / "sub"
    tree.mkdir(parents=True)
    (tree / "f").write_text("y")
    files.remove(link)
    files.remove(tmp_path / "tree")
    files.remove(tmp_path / "absent")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["target"]
    assert (target / "keep.txt").read_text() == "x"


def test_staged_files_write_all_or_nothing(tmp_path):
    old = tmp_path / "a.txt"
    old.write_text("old")
    with files.staged_files([old, tmp_path / "b.txt"]) as (sa, sb):
        assert sa.read_text() == "old"  # an existing destination is staged for in-place edits
        sa.write_text("new")
        sb.write_text("b")
        (sb.parent / "b.txt.aux.xml").write_text("<x/>")  # a writer's sidecar follows its file
    assert old.read_text() == "new" and (tmp_path / "b.txt").read_text() == "b"
    assert (tmp_path / "b.txt.aux.xml").exists()
    with pytest.raises(RuntimeError):
        with files.staged_files([old, tmp_path / "c.txt"]) as (sa, sc):
            sa.write_text("newer")
            raise RuntimeError("second writer failed")
    assert old.read_text() == "new" and not (tmp_path / "c.txt").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.txt", "b.txt", "b.txt.aux.xml"]
    with pytest.raises(GeoblockIOError, match="does not exist"):
        with files.staged_files([tmp_path / "nodir" / "x.txt"]):
            pass


def test_atomic_directory_never_replaces_a_directory_holding_foreign_files(tmp_path):
    """A mistyped output directory (``--out .``) must not delete the user's files."""
    from geoblock.errors import OutputDirectoryError

    out = tmp_path / "out"
    out.mkdir()
    (out / "thesis.txt").write_text("precious")
    with pytest.raises(OutputDirectoryError, match=r"holds 'thesis.txt'"):
        with files.atomic_directory(out, replaces=lambda e: e.suffix == ".png"):
            raise AssertionError("must not be entered")
    assert (out / "thesis.txt").read_text() == "precious"
    (out / "thesis.txt").unlink()
    (out / "old.png").write_bytes(b"")
    with files.atomic_directory(out, replaces=lambda e: e.suffix == ".png") as tmp:
        files.write_text(tmp / "new.png", "")
    assert [p.name for p in out.iterdir()] == ["new.png"]
    with pytest.raises(OutputDirectoryError, match="new.png"):  # no rule: only empty is replaced
        with files.atomic_directory(out):
            pass

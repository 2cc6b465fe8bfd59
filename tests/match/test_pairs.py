"""Pair selection from the images' footprints on the DEM (:mod:`geoblock.match.pairs`), on
blocks of synthetic cameras whose overlaps and convergence angles are known exactly: north-up
2 m cameras of 1000 x 1000 px (2 km footprints) whose centres are laid on a grid, over a flat
DEM; the ray of a camera with ``row_u = t * 0.5`` px/m leans ``atan(t)`` from the vertical,
north-south."""

from __future__ import annotations

import math

import numpy as np
import pytest

from geoblock import coords
from geoblock.dem import ConstantDem
from geoblock.errors import MatchError
from geoblock.match import select_pairs
from geoblock.match.pairs import _pair_geometry, _Plane, footprint
from geoblock.testing.synthetic import AffineCamera

GSD = 2.0
SIDE_PX = 1000
DEM = ConstantDem(100.0)


def camera(east_m: float, north_m: float, tilt: float = 0.0, lon0: float = 7.0,
           lat0: float = 43.0) -> AffineCamera:
    """A camera whose footprint's centre is ``east_m, north_m`` from ``lon0, lat0`` (on the
    100 m DEM), leaning ``atan(tilt)`` north-south."""
    lon, lat, _ = coords.LocalFrame(lon0, lat0, 100.0).to_geodetic(
        np.array([east_m]), np.array([north_m]), np.array([0.0]))
    c = (SIDE_PX - 1) / 2
    return AffineCamera((SIDE_PX, SIDE_PX), (float(lon[0]), float(lat[0]), 100.0),
                        [[c, 0.0, -1 / GSD, tilt / GSD], [c, 1 / GSD, 0.0, 0.0]])


def block(rows: int, cols: int, overlap: float = 0.2, **kw: float) -> dict[str, AffineCamera]:
    """``rows x cols`` cameras, ``overlap`` of their side shared with each neighbour."""
    step = SIDE_PX * GSD * (1 - overlap)
    return {f"r{r:02d}c{c:02d}": camera(c * step, -r * step, **kw)
            for r in range(rows) for c in range(cols)}


def test_candidates_are_the_overlapping_pairs_and_overlaps_are_the_shared_areas():
    cams = block(4, 5)
    graph = select_pairs(cams, DEM, min_overlap=0.0, max_pairs_per_image=None)
    # the sweep finds exactly the pairs that overlap (brute force over all pairs)
    fps = [_Plane.of(footprint(m, DEM)) for m in cams.values()]
    brute = {(i, j) for i in range(len(fps)) for j in range(i + 1, len(fps))
             if _pair_geometry(fps[i], fps[j])[0] > 0}
    found = {tuple(p) for p, f in zip(graph.pairs.tolist(), graph.overlap, strict=True)
             if f > 0}
    assert found == brute
    # side neighbours share 20 % of a footprint, diagonal ones 4 %: each to within the
    # lattice's step (1/15 of the side)
    ids = list(cams)
    for (i, j), f in zip(graph.pairs, graph.overlap, strict=True):
        (ri, ci), (rj, cj) = (divmod(k, 5) for k in (i, j))
        if f == 0:
            continue
        dr, dc = abs(ri - rj), abs(ci - cj)
        expected = 0.2 if dr + dc == 1 else 0.04
        assert abs(f - expected) <= 1 / 15 * (1 if dr + dc == 1 else 0.2 + 0.2) + 1e-9, (
            ids[i], ids[j], f)
    side = graph.overlap[np.abs(np.diff(graph.pairs, axis=1)).ravel() == 1]
    assert 0.13 <= side.min() and side.max() <= 0.27
    assert len(graph.components()) == 1 and not graph.unpaired()


def test_convergence_is_the_angle_between_the_lines_of_sight():
    t = 0.2  # atan(0.2) = 11.31 deg each way
    cams = {"fore": camera(0.0, 0.0, tilt=t), "aft": camera(0.0, 0.0, tilt=-t),
            "nadir": camera(0.0, 0.0)}
    graph = select_pairs(cams, DEM)
    angle = dict(zip(map(tuple, graph.pairs.tolist()), graph.convergence_deg, strict=True))
    assert angle[(0, 1)] == pytest.approx(2 * math.degrees(math.atan(t)), abs=0.05)
    assert angle[(0, 2)] == pytest.approx(math.degrees(math.atan(t)), abs=0.05)
    # the lower bound (stereo) drops the pairs under it, and says so
    stereo = select_pairs(cams, DEM, min_convergence_deg=15.0)
    assert stereo.selected.tolist() == [[0, 1]]
    assert stereo.unpaired() == ("nadir",)
    assert "nadir (no pair within the thresholds)" in stereo.report()
    assert stereo.counts()["convergence"] == 2


def test_the_cap_keeps_the_largest_overlaps_and_never_disconnects():
    cams = block(3, 6)
    full = select_pairs(cams, DEM, min_overlap=0.0, max_pairs_per_image=None)
    capped = select_pairs(cams, DEM, min_overlap=0.0, max_pairs_per_image=2)
    assert len(capped.components()) == 1 and not capped.unpaired()
    assert len(capped.selected) < len(full.selected)
    # a spanning tree (n - 1 pairs) at least, which may give an image its 4 side neighbours;
    # the pairs beyond the tree only between images under the cap
    assert len(cams) - 1 <= len(capped.selected) <= len(cams) - 1 + len(cams) * 2 // 2
    assert capped.degree().max() <= 4
    # a strip with a cap of 1: the chain survives whole
    strip = select_pairs(block(1, 6), DEM, max_pairs_per_image=1)
    assert strip.selected.tolist() == [[k, k + 1] for k in range(5)]
    # the diagonal pairs (4 %) go before the side ones (20 %)
    kept = capped.overlap[capped.status == "selected"]
    dropped = capped.overlap[capped.status == "cap"]
    assert np.median(kept) > np.median(dropped)
    # the threshold on overlap: the diagonal pairs are below 10 %
    default = select_pairs(cams, DEM, max_pairs_per_image=None)
    assert (default.overlap[default.status == "selected"] > 0.1).all()
    assert default.counts()["overlap"] > 0


def test_islands_and_images_without_pair_are_named_before_matching():
    west = block(2, 2)
    east = {f"e{k}": m for k, m in enumerate(block(1, 2, lon0=7.5).values())}
    lone = {"lone": camera(0.0, 0.0, lon0=8.0)}
    off = {"off": AffineCamera.example()}  # near Nice, outside the DEM below
    from geoblock.dem import GridDem

    # 6.5-8.5 E, 42.5-43.5 N (north-up, 0.01 degree posts)
    dem = GridDem(np.full((100, 200), 100.0), (0.01, 0.0, 6.5, 0.0, -0.01, 43.5))
    graph = select_pairs({**west, **east, **lone, **off}, dem)
    assert graph.components() == [tuple(west), tuple(east)]
    assert graph.unpaired() == ("lone", "off")
    report = graph.report()
    assert "component 1: 4 images: r00c00, r00c01, r01c00, r01c01" in report
    assert "component 2: 2 images: e0, e1" in report
    assert "lone (overlaps no other image)" in report
    assert "off (no footprint on the DEM)" in report
    assert "2 components, 2 image(s) with no pair" in graph.summary()
    # many islands: the first ones named, the others counted
    short = graph.report(max_names=1)
    assert "component 1: 4 images: r00c00, ... (3 more)" in short
    assert "... 1 more components of 2-2 images" in short


def test_hundreds_of_images_in_seconds_with_a_linear_number_of_candidates():
    cams = block(20, 25)
    graph = select_pairs(cams, DEM)
    # 8 neighbours at most: fewer than 4 candidate pairs per image, 2 selected (the sides)
    assert len(graph.pairs) <= 4 * len(cams)
    assert len(graph.selected) == 20 * 24 + 19 * 25
    assert len(graph.components()) == 1


@pytest.mark.parametrize("kw", [{"min_overlap": 1.5}, {"max_pairs_per_image": 0},
                                {"min_convergence_deg": 20.0, "max_convergence_deg": 10.0},
                                {"grid": 1}])
def test_bad_thresholds_are_refused(kw):
    with pytest.raises(MatchError, match=next(iter(kw)).split("_")[0]):
        select_pairs(block(1, 2), DEM, **kw)


def test_cli_pairs_only_reports_the_graph_with_the_block_files_thresholds(triplet, tmp_path):
    from click.testing import CliRunner

    from geoblock.cli.main import build_cli

    outdir, _ = triplet
    text = (outdir / "block.toml").read_text()
    block = outdir / "block-stereo.toml"
    block.write_text(text.replace("[outputs]", "[match]\nmin_convergence_deg = 15.0\n\n"
                                  "[outputs]"))

    def run(*args):
        return CliRunner().invoke(build_cli(), ["match", *map(str, args)])

    result = run(outdir / "block.toml", "--pairs-only")
    assert result.exit_code == 0, result.output
    assert "3 images, 3 candidate pairs, 3 selected, 1 component" in result.output
    assert "a & b: overlap" in result.output and "convergence 24.0 deg, selected" in result.output
    # the models are enough for the graph: a block without rasters (points only)
    bare = outdir / "block-bare.toml"
    bare.write_text("\n".join(line for line in text.splitlines()
                              if not line.startswith("raster")))
    result = run(bare, "--pairs-only")
    assert result.exit_code == 0 and "3 selected, 1 component" in result.output, result.output
    # the block file's [match] table, and the command line over it
    result = run(block, "--pairs-only")
    assert result.exit_code == 0, result.output
    assert "1 selected (not: 2 convergence)" in result.output
    assert "no pair: c (no pair within the thresholds)" in result.output
    result = run(block, "--pairs-only", "--min-convergence", "0", "--max-pairs-per-image", "1")
    assert "2 selected (not: 1 cap)" in result.output, result.output
    # the table survives writing the block back
    from geoblock.io.blocks import read_block, write_block

    copy = write_block(tmp_path / "copy.toml", read_block(block))
    assert dict(read_block(copy).match) == {"min_convergence_deg": 15.0}
    # a bad table is refused naming the file and the key
    block.write_text(text.replace("[outputs]", "[match]\nmin_overlaps = 0.2\n\n[outputs]"))
    result = run(block, "--pairs-only")
    assert result.exit_code == 1 and "unknown key 'match.min_overlaps'" in result.output
    block.write_text(text.replace("[outputs]", "[match]\nmin_overlap = 2.0\n\n[outputs]"))
    result = run(block, "--pairs-only")
    assert result.exit_code == 2 and "[match]: match option min_overlap must be in [0, 1]" \
        in result.output


def test_footprints_as_tasks_give_the_same_graph():
    cams = block(3, 4)
    one = select_pairs(cams, DEM, scheduler="synchronous")
    many = select_pairs(cams, DEM, scheduler="threads")
    for name in ("pairs", "overlap", "convergence_deg", "status"):
        np.testing.assert_array_equal(getattr(one, name), getattr(many, name))


def test_a_block_across_the_antimeridian():
    here = select_pairs(block(2, 3), DEM, min_overlap=0.0, max_pairs_per_image=None)
    across = select_pairs(block(2, 3, lon0=179.985), DEM, min_overlap=0.0,
                          max_pairs_per_image=None)
    # the footprints' centres at 179.985 E and 179.995, 179.976 W
    lon = np.array([m._origin[0] for m in block(2, 3, lon0=179.985).values()])
    assert (lon > 179.98).any() and (lon < -179.97).any()
    np.testing.assert_array_equal(here.pairs[here.overlap > 0],
                                  across.pairs[across.overlap > 0])
    np.testing.assert_allclose(here.overlap[here.overlap > 0],
                               across.overlap[across.overlap > 0], atol=0.02)

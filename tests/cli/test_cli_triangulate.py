"""``geoblock triangulate``: the shareloc Nice pair from the command line, a block file, and
the refusals (before any work)."""

from __future__ import annotations

import csv
import io

import numpy as np
import pytest

from geoblock import coords

LEFT = "shareloc/rpc/PHR1B_P_201709281038045_SEN_PRG_FC_178608-001.geom"
RIGHT = "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.geom"
#: shareloc tests/data/triangulation/README (see tests/triangulation/test_triangulation.py)
POINTS = ("id,image,row,col\n"
          "p,L,10235.9310147135147417429834604,10121.0657280102386721409857273\n"
          "p,R,10018.4917330250955274095758796,10472.1832935943566553760319948\n"
          "q,L,5000,5000\n")
README_ECEF = (4584341.53074182, 572313.952956326, 4382784.34315186)


def _rows(text):
    return list(csv.DictReader(io.StringIO(text)))


@pytest.fixture
def pair(data_dir):
    return ["--model", str(data_dir / LEFT), "--image-id", "L",
            "--model", str(data_dir / RIGHT), "--image-id", "R"]


def test_the_shareloc_pair(runner, cli, tmp_path, pair):
    src = tmp_path / "tp.csv"
    src.write_text(POINTS)
    result = runner.invoke(cli, ["triangulate", str(src), *pair])
    assert result.exit_code == 0, result.output
    rows = _rows(result.stdout)
    assert list(rows[0]) == ["id", "lon", "lat", "h", "miss_m", "rays", "rms_px", "sigma_e",
                             "sigma_n", "sigma_h", "v_row_L", "v_col_L", "v_row_R", "v_col_R",
                             "status"]
    p, q = rows
    assert p["status"] == "converged" and p["rays"] == "2"
    xyz = coords.geodetic_to_ecef(float(p["lon"]), float(p["lat"]), float(p["h"]))
    assert np.max(np.abs(np.array(xyz) - README_ECEF)) < 1e-3
    assert 0.5 < float(p["miss_m"]) < 1.2 and float(p["sigma_h"]) > 0
    assert q["status"] == "no_intersection" and q["rays"] == "1" and q["lon"] == "nan"
    assert q["v_row_R"] == "nan"
    assert "1 of 2 points have fewer than two usable rays" in result.stderr


def test_output_checked_before_any_work_and_overwrite(runner, cli, tmp_path, pair):
    src = tmp_path / "tp.csv"
    src.write_text(POINTS)
    out = tmp_path / "ground.csv"
    out.write_text("mine\n")
    result = runner.invoke(cli, ["triangulate", str(src), *pair, "-o", str(out)])
    assert result.exit_code != 0 and "exists; pass --overwrite" in result.output
    assert out.read_text() == "mine\n"
    result = runner.invoke(cli, ["triangulate", str(src), *pair, "-o", str(out), "--overwrite"])
    assert result.exit_code == 0, result.output
    assert _rows(out.read_text())[0]["status"] == "converged"
    # an output that is also an input is refused always
    result = runner.invoke(cli, ["triangulate", str(src), *pair, "-o", str(src), "--overwrite"])
    assert result.exit_code != 0 and src.read_text() == POINTS


def test_a_block_file_gives_models_and_points(runner, cli, tmp_path, data_dir):
    (tmp_path / "image.csv").write_text(POINTS)
    (tmp_path / "block.toml").write_text(
        'version = 1\nmethod = "rpcv0"\n[points]\nimage = "image.csv"\n'
        f'[[images]]\nid = "L"\nmodel = "{data_dir / LEFT}"\n'
        f'[[images]]\nid = "R"\nmodel = "{data_dir / RIGHT}"\n')
    result = runner.invoke(cli, ["triangulate", str(tmp_path / "block.toml"),
                                 "-o", str(tmp_path / "out.csv")])
    assert result.exit_code == 0, result.output
    assert _rows((tmp_path / "out.csv").read_text())[0]["status"] == "converged"
    result = runner.invoke(cli, ["triangulate", str(tmp_path / "block.toml"), "--model", "x"])
    assert result.exit_code == 2 and "--model applies to POINTS" in result.output


def test_refusals_name_the_cause(runner, cli, tmp_path, pair, affine, model_path):
    src = tmp_path / "tp.csv"
    src.write_text("id,image,row,col\na,L,1,1\nb,R,1,1\n")
    result = runner.invoke(cli, ["triangulate", str(src), *pair])
    assert result.exit_code == 2 and "no point of POINTS is measured in two images" in \
        result.output
    src.write_text("id,row,col\na,1,1\na,1,1\n")
    result = runner.invoke(cli, ["triangulate", str(src), *pair])
    assert result.exit_code == 2 and "no 'image' column" in result.output
    result = runner.invoke(cli, ["triangulate", str(src), "--model", model_path])
    assert result.exit_code == 2 and "two or more images" in result.output
    result = runner.invoke(cli, ["triangulate", str(src), *pair, "--image-id", "Z"])
    assert result.exit_code == 2 and "once per --model" in result.output
    src.write_text("id,image,row,col\na,L,1,1\na,X,1,1\n")
    result = runner.invoke(cli, ["triangulate", str(src), *pair])
    assert result.exit_code == 1 and "image(s) ['X']" in result.output


def test_sigma_column_and_default(runner, cli, tmp_path, pair):
    src = tmp_path / "tp.csv"
    src.write_text(POINTS.splitlines()[0] + ",sigma\n"
                   + "\n".join(line + ",0.25" for line in POINTS.splitlines()[1:]) + "\n")
    with_col = _rows(runner.invoke(cli, ["triangulate", str(src), *pair]).stdout)[0]
    src.write_text(POINTS)
    default = _rows(runner.invoke(cli, ["triangulate", str(src), *pair]).stdout)[0]
    given = _rows(runner.invoke(cli, ["triangulate", str(src), *pair, "--sigma-px", "0.25"]
                                ).stdout)[0]
    assert float(with_col["sigma_h"]) == pytest.approx(float(given["sigma_h"]))
    assert float(default["sigma_h"]) == pytest.approx(4 * float(given["sigma_h"]))

"""The DIMAP v2 (SPOT 6/7, Pleiades) line-of-sight model against CNES's reference grid, the
documents' own RFM, shareloc's expected values, and the conformance kit."""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np
import pytest
from geoblock_spot.dimap import DimapFormatError
from geoblock_spot.dimap2 import dimap2_model, is_dimap2, read_dimap2

from geoblock import coords
from geoblock.errors import ModelFormatError
from geoblock.io import open_model, write_model
from geoblock.models.linescan import LinescanModel
from geoblock.testing import SensorModelContract

SPOT6 = "cosicorr3d/test_dataset/SPOT6.XML"
PHR_2018 = "shareloc/rpc/PHRDIMAP_P1BP--2018122638935449CP.XML"
PHR_2017 = "shareloc/rpc/PHRDIMAP_P1BP--2017030824934340CP.XML"
GRID_2018 = "shareloc/ellipsoide/P1BP--2018122638935449CP/GRID_P1BP--2018122638935449CP.tif"
GRID_2017 = "shareloc/geoide/P1BP--2017030824934340CP/GRID_P1BP--2017030824934340CP.tif"
GEOID = "shareloc/dtm/geoid/egm96_15.gtx"


def _path(data_dir, rel):
    path = data_dir / rel
    if not path.exists():
        pytest.skip(f"{rel} not in the test data")
    return path


def _grid(data_dir, rel):
    """CNES location grid: (row, col) of the nodes in geoblock pixels, lon/lat bands, heights.

    shareloc's grids put the first pixel's centre at 0.5 (top-left convention): geoblock's
    coordinates are 0.5 less.
    """
    rasterio = pytest.importorskip("rasterio")
    with rasterio.open(_path(data_dir, rel)) as ds:
        bands = ds.read()
        tr, tags = ds.transform, ds.tags()
    ny, nx = bands.shape[1:]
    rows = tr.f + tr.e * np.arange(ny) - 0.5
    cols = tr.c + tr.a * np.arange(nx) - 0.5
    heights = [float(tags[f"ALTITUDE_B{b}"]) for b in range(0, bands.shape[0], 2)]
    return rows, cols, bands[0::2], bands[1::2], heights


def _distance_m(lon_a, lat_a, lon_b, lat_b, h):
    a = np.stack(coords.geodetic_to_ecef(lon_a, lat_a, h), axis=-1)
    b = np.stack(coords.geodetic_to_ecef(lon_b, lat_b, h), axis=-1)
    return np.linalg.norm(a - b, axis=-1)


# ------------------------------------------------------------------------------ reader
def test_reads_spot6_refined_model(data_dir):
    meta = read_dimap2(_path(data_dir, SPOT6))
    assert (meta.format, meta.profile, meta.mission) == ("dimap-v2", "S6_SENSOR", "SPOT 6")
    assert meta.shape == (25533, 25669)
    assert meta.epoch == "2018-09-15T18:19:26.678361000Z"
    assert meta.line_period_s == pytest.approx(229.110269e-6, rel=1e-12)
    assert meta.ephemeris_time_s.shape == (48,) and meta.quaternions.shape == (188, 4)
    assert meta.quaternion_polynomial is None
    assert meta.velocity_frame == "earth-fixed"
    assert meta.first_detector == 1
    np.testing.assert_array_equal(meta.psi_x_coefficients, [-0.02675844533, 0.0000022171403835])
    np.testing.assert_array_equal(meta.psi_y_coefficients, [0.0, 0.0])
    assert len(meta.vertices) == 4 and (meta.centre.row, meta.centre.col) == (12766.0, 12834.0)


def test_reads_pleiades_internal_document(data_dir):
    meta = read_dimap2(_path(data_dir, PHR_2018))
    assert (meta.format, meta.mission, meta.shape) == ("phr-internal", "PHR 1B", (38248, 40000))
    assert meta.line_period_s == pytest.approx(73.5e-6, rel=1e-12)
    # inertial velocities on ECEF axes: V - dP/dt = omega x P
    assert meta.velocity_frame == "inertial"
    poly = meta.quaternion_polynomial
    # OFFSET 38936.90625 s after UTC midnight; START 10:48:55.449 = 38935.449 s
    assert poly.offset_s == pytest.approx(38936.90625 - 38935.449, abs=1e-9)
    assert poly.scale_s == 1.625 and poly.coefficients.shape == (4, 4)
    np.testing.assert_array_equal(meta.psi_x_coefficients, [-0.01422, 7.11e-07])
    np.testing.assert_array_equal(meta.psi_y_coefficients, [8e-05])


def test_is_dimap2_leaves_rpc_and_v1_files_alone(data_dir):
    assert is_dimap2(_path(data_dir, SPOT6)) and is_dimap2(_path(data_dir, PHR_2017))
    for rel in ("rpcm/test_rpc_files/rpc_SPOT6.xml", "cosicorr3d/test_dataset/SPOT5.DIM",
                "shareloc/rpc/RPC_PHR1B_P_201709281038045_SEN_PRG_FC_178608-001.XML"):
        assert not is_dimap2(_path(data_dir, rel))


# ------------------------------------------------------------------------------ CNES grid
def test_cnes_reference_grid(data_dir):
    """Every node of CNES's direct-location grid (65 x 65 nodes over the whole image, 9
    heights from -30 to 4900 m) within 2 cm. Measured: max 5.4 mm, RMS 4.1 mm (the rest is
    the interpolation schemes). Each wrong convention moves nodes by >= 0.5 m: detector
    index off by one (0.54 m), row 0 one line later (0.53 m), look angles instead of
    tangents (0.72 m), velocities as given (1.2 km), the WGS84_Attitudes table (2.4 m)."""
    model = dimap2_model(_path(data_dir, PHR_2018))
    rows, cols, lon, lat, heights = _grid(data_dir, GRID_2018)
    assert (rows[0], rows[-1], cols[0], cols[-1]) == pytest.approx(
        (0.0, model.shape[0] - 1.0, 0.0, model.shape[1] - 1.0), abs=1e-3)
    r, c = np.meshgrid(rows, cols, indexing="ij")
    errors = []
    for k, h in enumerate(heights):
        g = model.backproject(r, c, h)
        errors.append(_distance_m(g.lon, g.lat, lon[k], lat[k], h))
        proj = model.project(lon[k], lat[k], h)
        assert np.max(np.hypot(proj.row - r, proj.col - c)) < 0.04  # 0.5 m pixels
    errors = np.array(errors)
    assert errors.shape == (9, 65, 65)
    assert np.max(errors) < 0.02
    assert np.sqrt(np.mean(errors**2)) < 0.01


def test_shareloc_2017_grid_values(data_dir):
    """The 2017 scene's grid (geoid heights): its first node agrees within 0.01 px, but its
    column axis does not describe this document's columns (node j of 513 lies near column
    105.5 j, not the 78.03 j of its geotransform, and its last node at column ~57 400 of a
    39 951-column image). shareloc's expected values, interpolated in that grid's first cell,
    are reproduced once the cell's true column span is used."""
    from geoblock.dem.geoid import Geoid

    geoid = Geoid(_path(data_dir, GEOID))
    model = dimap2_model(_path(data_dir, PHR_2017))
    rows, cols, lon, lat, heights = _grid(data_dir, GRID_2017)
    n = geoid.undulation(lon, lat)
    first = [model.project(lon[k][0, :2], lat[k][0, :2], h + n[k][0, :2])
             for k, h in enumerate(heights)]
    for p in first:
        assert abs(p.row[0] - rows[0]) < 0.01 and abs(p.col[0] - cols[0]) < 0.01
    # the cell's true column span, from the model: ~105.5 px where the geotransform says 78.03
    span = first[0].col[1] - first[0].col[0]
    assert 105.0 < span < 106.0
    # shareloc test_localization l.496-510: inverse of (57.2167252772905, 21.9587514585812,
    # 10 m above the geoid) -> (row 50.5, col 10.0), i.e. geoblock (50.0, 9.5) in the grid's
    # column scale; in this document's columns that is 9.5 * span / 78.03
    lon0, lat0 = 57.2167252772905, 21.9587514585812
    p = model.project(lon0, lat0, 10.0 + float(geoid.undulation(lon0, lat0)))
    assert p.row == pytest.approx(50.0, abs=0.05)
    assert p.col == pytest.approx(9.5 * span / (cols[1] - cols[0]), abs=0.05)
    # l.276-290: (row 100.5, col 50.5, h 100) -> (57.2170054518422, 21.9590529453258)
    c_true = 50.0 * span / (cols[1] - cols[0])
    h = 100.0 + float(geoid.undulation(57.217, 21.959))
    g = model.backproject(100.0, c_true, h)
    assert _distance_m(g.lon, g.lat, 57.2170054518422, 21.9590529453258, h) < 0.5
    # taken at face value (col 50) the shareloc value is 9 m (17.6 columns) away
    g = model.backproject(100.0, 50.0, h)
    assert 8.0 < _distance_m(g.lon, g.lat, 57.2170054518422, 21.9590529453258, h) < 10.0


# ------------------------------------------------------------------------------ RFM
@pytest.mark.parametrize("rel", [PHR_2018, PHR_2017])
def test_agrees_with_the_documents_rfm(data_dir, rel):
    """A 21 x 21 grid over the whole image at the RFM's lowest, middle and highest heights,
    projected through both models. Measured: max 0.02 px (RMS 0.01 px) for both documents,
    the RFM's own fitting error (MODEL_PRECISION_ROW/COL ~1e-3 in normalised units)."""
    path = _path(data_dir, rel)
    model = open_model(path)
    rpc = open_model(path, model="rpc")
    assert isinstance(model, LinescanModel) and type(rpc).__name__ == "RpcModel"
    assert rpc.shape == model.shape
    rows, cols = model.shape
    r, c = np.meshgrid(np.linspace(0, rows - 1, 21), np.linspace(0, cols - 1, 21), indexing="ij")
    h0, h1 = rpc.rpc.height_off - rpc.rpc.height_scale, rpc.rpc.height_off + rpc.rpc.height_scale
    d = []
    for h in (h0, 0.5 * (h0 + h1), h1):
        g = model.backproject(r, c, h)
        p = rpc.project(g.lon, g.lat, h)
        d.append(np.hypot(p.row - r, p.col - c))
    d = np.array(d)
    assert np.max(d) < 0.05
    assert np.sqrt(np.mean(d**2)) < 0.02


# ------------------------------------------------------------------------------ SPOT 6
def test_spot6_product_extent(data_dir):
    """SPOT 6 states no RFM in its DIM file (RPC_*.XML is a separate file, not in the test
    data); its Dataset_Extent corners and centre (no height stated) are all within 6 px
    (2.1 m GSD) at one terrain height (800 m, the Mojave near Ridgecrest), well inside the
    product's ~35 m accuracy."""
    meta = read_dimap2(_path(data_dir, SPOT6))
    model = dimap2_model(meta)
    points = list(meta.vertices) + [meta.centre]
    lon, lat = np.array([p.lon for p in points]), np.array([p.lat for p in points])
    row, col = np.array([p.row for p in points]), np.array([p.col for p in points])
    heights = np.arange(0.0, 3001.0, 100.0)
    worst = []
    for h in heights:
        p = model.project(lon, lat, h)
        worst.append(np.max(np.hypot(p.row - row, p.col - col)))
    assert min(worst) < 6.0
    assert heights[int(np.argmin(worst))] == 800.0


@pytest.mark.parametrize("h", [-500.0, 9000.0])
def test_spot6_ground_to_image_converges_over_the_scene(data_dir, h):
    model = dimap2_model(_path(data_dir, SPOT6))
    rows, cols = model.shape
    r, c = np.meshgrid(np.linspace(0, rows - 1, 60), np.linspace(0, cols - 1, 60), indexing="ij")
    g = model.backproject(r, c, h)
    (pr, pc), status = model.project_with_status(g.lon, g.lat, h)
    assert np.all(status == 0)
    assert np.max(np.hypot(pr - r, pc - c)) < 1e-6


# ------------------------------------------------------------------------------ refusals
def _write(tree, tmp_path, name="DIM_TEST.XML"):
    path = tmp_path / name
    tree.write(path, encoding="utf-8", xml_declaration=True)
    return path


def test_inertial_frame_is_refused(data_dir, tmp_path):
    tree = ET.parse(_path(data_dir, SPOT6))
    code = tree.getroot().find("Geometric_Data/Refined_Model/Coordinate_Reference_System/"
                               "Geodetic_CRS/GEODETIC_CRS_CODE")
    code.text = "J2000"
    with pytest.raises(DimapFormatError, match="Geodetic_CRS.*inertial frames are not supported"):
        read_dimap2(_write(tree, tmp_path))


def test_attitude_not_earth_fixed_is_refused(data_dir, tmp_path):
    """Quaternions rotated by 3 degrees about the Earth's axis (an inertial/ECEF mix-up at a
    small Earth rotation angle) put the scene centre ~340 km away: refused."""
    tree = ET.parse(_path(data_dir, SPOT6))
    a = np.radians(3.0)
    rz = np.array([np.cos(a / 2), 0.0, 0.0, np.sin(a / 2)])
    for e in tree.getroot().iter("Quaternion"):
        w, x, y, z = (float(e.find(f"Q{k}").text) for k in range(4))
        q = np.array([  # rz (x) q, Hamilton
            rz[0] * w - rz[3] * z, rz[0] * x - rz[3] * y, rz[0] * y + rz[3] * x,
            rz[0] * z + rz[3] * w])
        for k in range(4):
            e.find(f"Q{k}").text = repr(float(q[k]))
    with pytest.raises(DimapFormatError, match="scene centre.*km away.*not sensor -> ECEF"):
        dimap2_model(_write(tree, tmp_path))


def test_attitude_must_cover_the_image(data_dir, tmp_path):
    tree = ET.parse(_path(data_dir, SPOT6))
    parent = tree.getroot().find("Geometric_Data/Refined_Model/Attitudes/Quaternion_List")
    for q in parent.findall("Quaternion")[:100]:
        parent.remove(q)
    with pytest.raises(DimapFormatError, match="Quaternion_List.*does not cover the image"):
        dimap2_model(_write(tree, tmp_path))


def test_bad_velocities_and_line_period_are_refused(data_dir, tmp_path):
    tree = ET.parse(_path(data_dir, SPOT6))
    v = tree.getroot().find("Geometric_Data/Refined_Model/Ephemeris/Point_List/Point/"
                            "VELOCITY_XYZ")
    v.text = "0 0 0"
    with pytest.raises(DimapFormatError, match="match neither the derivative"):
        read_dimap2(_write(tree, tmp_path))
    tree = ET.parse(_path(data_dir, SPOT6))
    lp = tree.getroot().find("Geometric_Data/Refined_Model/Time/Time_Stamp/LINE_PERIOD")
    lp.set("unit", "millisecond")
    with pytest.raises(DimapFormatError, match="END - START"):
        read_dimap2(_write(tree, tmp_path))


# ------------------------------------------------------------------------------ open_model
def test_open_model_dispatch_and_json_round_trip(data_dir, tmp_path):
    """The physical model answers when no model is named (geoblock-rpc is trylast);
    ``model="rpc"`` gives the document's RFM."""
    path = _path(data_dir, SPOT6)
    model = open_model(path)
    assert isinstance(model, LinescanModel)
    assert isinstance(open_model(path, model="linescan"), LinescanModel)
    with pytest.raises(ModelFormatError, match="RPC_SPOT6_P_201809151819247"):
        open_model(path, model="rpc")  # the RFM is in a separate file
    with pytest.raises(ModelFormatError, match="unknown option"):
        open_model(path, bogus=1)
    dg = open_model(path, parameters="dg", accuracy_m=16.0)
    assert np.all(np.isfinite(dg.parameters.sigmas[:9]))
    with pytest.raises(ValueError, match="accuracy_m"):
        dimap2_model(path, parameters="dg")
    again = open_model(write_model(model, tmp_path / "spot6.json"))
    lon, lat = np.array([-117.6, -117.4]), np.array([35.6, 35.8])
    np.testing.assert_array_equal(again.project(lon, lat, 800.0), model.project(lon, lat, 800.0))


class TestDimap2Contract(SensorModelContract):
    """The conformance kit on the full SPOT 6 scene (linescan parameters) and the Pleiades
    internal document with the DG set (finite sigmas give finite-difference steps above the
    ground -> image solver's 1e-9 px noise)."""

    check_options = {"n": 4}
    parameter_set_options = {"dg": {"accuracy_m": 10.0}, "physical": {"accuracy_m": 10.0},
                             "jitter": {"accuracy_m": 10.0}}

    @pytest.fixture(params=["spot6", "phr-dg"])
    def model(self, request, data_dir):
        if request.param == "spot6":
            return dimap2_model(_path(data_dir, SPOT6))
        return dimap2_model(_path(data_dir, PHR_2018), parameters="dg", accuracy_m=5.0)


# ---- options given directly to dimap2_model (not through the plugin's hook)
@pytest.mark.parametrize("step", [0, 0.0, -1.0, float("nan"), float("inf"), 11.0, "x", True,
                                  None])
def test_direct_call_refuses_a_bad_attitude_step_naming_the_file(step, data_dir):
    path = _path(data_dir, PHR_2018)
    with pytest.raises(DimapFormatError, match="attitude_step_s") as info:
        dimap2_model(path, attitude_step_s=step)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("heights", ["abc", "12", (1.0,), (1.0, 2.0, 3.0), ("a", 1.0),
                                     (5.0, 1.0), (0.0, float("nan")), 7])
def test_direct_call_refuses_a_bad_height_range_naming_the_file(heights, data_dir):
    path = _path(data_dir, SPOT6)
    with pytest.raises(DimapFormatError, match="height_range") as info:
        dimap2_model(path, height_range=heights)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("accuracy", [0.0, -3.0, float("nan"), "ten"])
def test_direct_call_refuses_a_bad_accuracy_naming_the_file(accuracy, data_dir):
    path = _path(data_dir, SPOT6)
    with pytest.raises(DimapFormatError, match="accuracy_m") as info:
        dimap2_model(path, accuracy_m=accuracy)
    assert str(path) in str(info.value)


def test_direct_call_parameter_errors_name_the_file_and_keep_their_class(data_dir):
    from geoblock.errors import ParameterSetError

    path = _path(data_dir, SPOT6)
    for parameters in ("bogus", 3, "default"):
        with pytest.raises(ParameterSetError, match="parameters must be") as info:
            dimap2_model(path, parameters=parameters)
        assert str(path) in str(info.value)
    with pytest.raises(ParameterSetError, match="accuracy_m") as info:
        dimap2_model(path, parameters="dg")
    assert str(path) in str(info.value) and info.value.path == str(path)

"""RPC readers: every RPC-carrying file of shared/data opens, agrees with GDAL and the peers."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
from geoblock_rpc import plugin
from geoblock_rpc.model import RpcModel
from geoblock_rpc.readers import RPC00A_TO_B, read_rpc
from geoblock_rpc.rpc00b import Rpc00b
from rasterio.errors import NotGeoreferencedWarning
from rasterio.rpc import RPC
from rasterio.transform import RPCTransformer

import geoblock
from geoblock.errors import ModelFormatError, UnsupportedFormatError

#: relative path -> (exception, fragments the message must hold besides the file name)
NEGATIVE = {
    "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001_nogeo.tif":
        (ModelFormatError, ["GeoTIFF without RPC metadata", "RPB/_RPC.TXT sidecar"]),
    "shareloc/rpc/fake_rpc.txt": (ModelFormatError, ["no RPC coefficients", "LINE_OFF"]),
    "stereopipeline/tests/dg_example2.xml": (ModelFormatError, ["without an <RPB><IMAGE>"]),
    "cosicorr3d/test_dataset/SPOT6.XML":
        (ModelFormatError,
         ["no RPC coefficients", "RPC_SPOT6_P_201809151819247_SEN_4555226101.XML"]),
}

#: 178609: shareloc inverse_loc (lon, lat, 0) -> (col 100.5, row 200.5) in its top-left
#: convention (OSSIM's, = GDAL pixel/line); geoblock's pixel-centre convention is 0.5 less.
NICE_GROUND = (7.048662660737769592, 43.72774839443545858, 0.0)
NICE_EXPECTED_ROW_COL = (200.5 - 0.5, 100.5 - 0.5)
NICE_SOURCES = [
    "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.geom",
    "shareloc/rpc/RPC_PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.XML",
    "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif",
]


def _random_ground(rpc: Rpc00b, n: int, seed: int = 0, extent: float = 1.0):
    """n points uniformly in the normalised cube [-extent, extent]^3 of ``rpc``."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-extent, extent, size=(3, n))
    lon = rpc.long_off + u[0] * rpc.long_scale
    lat = rpc.lat_off + u[1] * rpc.lat_scale
    h = rpc.height_off + u[2] * rpc.height_scale
    return lon, lat, h


def _gdal_project(rpc_gdal: RPC, lon, lat, h):
    """GDAL's exact ground -> pixel/line (the RPC transformer's reverse direction), as
    geoblock (row, col): GDAL's pixel/line is (col + 0.5, row + 0.5)."""
    with RPCTransformer(rpc_gdal) as tr:
        line, pixel = tr.rowcol(lon, lat, zs=h, op=np.positive)
    return np.asarray(line) - 0.5, np.asarray(pixel) - 0.5


def _open(data_dir: Path, rel: str, **options):
    # model="rpc": DIMAP documents with a physical model (PHRDIMAP_*.XML, SPOT6.XML) open as
    # geoblock-spot's line-of-sight model when no model is named
    options.setdefault("model", "rpc")
    return geoblock.open_model(data_dir / rel, **options)


# ------------------------------------------------------------------------------ opening
def test_every_rpc_file_opens(data_dir, rpc_file, rpc_files):
    rel = rpc_file
    model = _open(data_dir, rel)
    assert isinstance(model, RpcModel)
    rpc, shape, extra = read_rpc(data_dir / rel)
    assert extra["format"] == rpc_files[rel]
    assert model.rpc == rpc
    if shape is not None:
        assert model.shape == shape
    assert model.rpc.source == str(data_dir / rel)


@pytest.mark.parametrize("rel", sorted(NEGATIVE))
def test_negative_files_are_refused_with_the_reason(data_dir, rel):
    exc, fragments = NEGATIVE[rel]
    with pytest.raises(exc) as info:
        _open(data_dir, rel)
    message = str(info.value)
    assert Path(rel).name in message
    for fragment in fragments:
        assert fragment in message


def test_unrecognised_text_file_returns_none_so_other_plugins_can_try(tmp_path):
    path = tmp_path / "notes.txt"
    path.write_text("LINE: not an RPC\nsomething else\n")
    assert plugin.geoblock_read_sensor_model(path, None, {}) is None
    with pytest.raises(UnsupportedFormatError, match="notes.txt"):
        geoblock.open_model(path)
    with pytest.raises(UnsupportedFormatError, match="notes.txt"):
        read_rpc(path)


def test_other_model_name_is_declined(data_dir):
    path = data_dir / "gdal-autotest/gcore/data/test_rpc.txt"
    assert plugin.geoblock_read_sensor_model(path, "affine-camera", {}) is None
    assert isinstance(plugin.geoblock_read_sensor_model(path, "rpc", {}), RpcModel)
    assert isinstance(geoblock.open_model(path, model="rpc"), RpcModel)


def test_geoblock_model_json_is_left_to_the_core(tmp_path):
    model = RpcModel.example()
    path = geoblock.write_model(model, tmp_path / "model.json")
    assert plugin.geoblock_read_sensor_model(path, None, {}) is None
    back = geoblock.open_model(path)
    assert back.rpc == model.rpc


def test_gdal_style_json_and_rpcm_json(tmp_path, data_dir):
    rpc = RpcModel.example().rpc
    path = tmp_path / "some.json"
    path.write_text(json.dumps(rpc.to_gdal()))
    assert read_rpc(path)[0] == rpc
    rpc2, shape, extra = read_rpc(data_dir / "rpcm/test_rpc_files/JAX_068_001_RGB.json")
    assert shape == (815, 746)
    assert extra["acquisition_date"] == "20141005160138"
    assert rpc2.line_off == 405.51806724276 and rpc2.samp_scale == 383.009070557184


# ------------------------------------------------------------------------------ parse checks
def test_wv3_20_ntf_offsets_and_scales_as_shareloc(data_dir):
    rpc = _open(data_dir, "shareloc/rpc/wv3_20.NTF").rpc
    assert (rpc.height_off, rpc.height_scale) == (31.0, 501.0)
    assert (rpc.lat_off, rpc.lat_scale) == (-34.5043, 0.0531)
    assert (rpc.long_off, rpc.long_scale) == (-58.6024, 0.0803)
    assert (rpc.line_off, rpc.line_scale) == (17495.0, 17996.0)
    assert (rpc.samp_off, rpc.samp_scale) == (20749.0, 21250.0)


@pytest.mark.parametrize("rel", NICE_SOURCES)
def test_nice_178609_inverse_loc_matches_shareloc(data_dir, rel):
    model = _open(data_dir, rel)
    row, col = model.project(*NICE_GROUND)
    np.testing.assert_allclose([row, col], NICE_EXPECTED_ROW_COL, atol=1e-2)


def test_nice_178609_three_sources_are_the_same_model(data_dir):
    models = [_open(data_dir, rel) for rel in NICE_SOURCES]
    lon, lat, h = _random_ground(models[0].rpc, 1000, extent=0.9)
    ref = np.array(models[0].project(lon, lat, h))
    for model in models[1:]:
        np.testing.assert_allclose(np.array(model.project(lon, lat, h)), ref, atol=1e-6)


def test_dimap_offsets_are_one_based(data_dir):
    rel = "shareloc/rpc/RPC_PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.XML"
    rpc, _, extra = read_rpc(data_dir / rel)
    assert (rpc.line_off, rpc.samp_off) == (11470.5 - 1, 20000.5 - 1)
    assert extra["offset_shift"] == -1.0
    assert rpc.has_validity_box and rpc.min_long == 7.039269536050538


def test_dimap_swapped_validity_box_is_repaired(data_dir):
    # rpc_SPOT6.xml states FIRST_LON 18.39 / FIRST_LAT -72.44 around LONG_OFF -72.27,
    # LAT_OFF 18.58: longitude and latitude are swapped in the file
    rpc, _, extra = read_rpc(data_dir / "rpcm/test_rpc_files/rpc_SPOT6.xml")
    assert extra["validity_box"] == "swapped lon/lat in the file, repaired"
    assert (rpc.min_long, rpc.min_lat) == (-72.4395036093, 18.3932164171)


def test_planet_l1a_and_l1b_same_model_different_normalisation(data_dir):
    """rpcm's test_rpc_comparison: "the two images have the same RPC model, but different
    sizes" (L1A 0.8x the L1B pixel grid): the same polynomials and ground normalisation,
    different LINE/SAMP_OFF/SCALE. So the *normalised* image coordinates are identical and
    the pixel coordinates are related by the affine map between the two normalisations."""
    a = _open(data_dir, "rpcm/test_rpc_files/rpc_PLANET_L1A.txt")
    b = _open(data_dir, "rpcm/test_rpc_files/rpc_PLANET_L1B.txt")
    ra, rb = a.rpc, b.rpc
    assert (ra.line_off, ra.samp_off) != (rb.line_off, rb.samp_off)
    assert (ra.line_scale, ra.samp_scale) != (rb.line_scale, rb.samp_scale)
    lon, lat, h = _random_ground(ra, 10_000, seed=3, extent=0.9)
    row_a, col_a = a.project(lon, lat, h)
    row_b, col_b = b.project(lon, lat, h)
    np.testing.assert_allclose((row_a - ra.line_off) / ra.line_scale,
                               (row_b - rb.line_off) / rb.line_scale, rtol=0, atol=1e-12)
    np.testing.assert_allclose((col_a - ra.samp_off) / ra.samp_scale,
                               (col_b - rb.samp_off) / rb.samp_scale, rtol=0, atol=1e-12)
    np.testing.assert_allclose(rb.line_off + (row_a - ra.line_off) * rb.line_scale / ra.line_scale,
                               row_b, rtol=0, atol=1e-8)


def test_phrdimap_height_range(data_dir):
    model = _open(data_dir, "shareloc/rpc/PHRDIMAP_P1BP--2018122638935449CP.XML")
    rpc = model.rpc
    assert (rpc.height_off, rpc.height_scale) == (575.0, 85.0)
    # shareloc's asserted "altitude range" (532.5, 617.5) is HEIGHT_OFF -/+ HEIGHT_SCALE / 2;
    # geoblock's height_range is the fitted range HEIGHT_OFF -/+ HEIGHT_SCALE
    assert (rpc.height_off - rpc.height_scale / 2, rpc.height_off + rpc.height_scale / 2) == (
        532.5, 617.5)
    assert model.height_range == (490.0, 660.0)
    assert model.shape == (38248, 40000)


def test_dg_isd_shape_and_satellite(data_dir):
    rpc, shape, extra = read_rpc(data_dir / "rpcm/test_rpc_files/rpc_WV2.xml")
    assert shape == (20289, 28244)
    assert extra["satellite_id"] == "WV02"
    assert (rpc.line_off, rpc.samp_off, rpc.err_bias) == (10108.0, 14104.0, 26.68)


def test_rpb_header_items(data_dir):
    rpc, shape, extra = read_rpc(data_dir / "gdal-autotest/gcore/data/md_dg.RPB")
    assert shape is None
    assert extra["satellite_id"] == "WV03" and extra["spec_id"] == "RPC00B"
    assert (rpc.err_bias, rpc.err_rand, rpc.line_off, rpc.samp_scale) == (1.49, 0.58, 812, 1152)


def test_ossim_polynomial_format_a_is_reordered(data_dir, tmp_path):
    src = data_dir / "shareloc/rpc/phr_gizeh/img1.geom"
    ref = read_rpc(src)[0]
    lines = []
    for line in src.read_text().splitlines():
        key, _, value = line.partition(":")
        if key.strip() == "polynomial_format":
            value = "  A"
        lines.append(f"{key}:{value}")
    text = "\n".join(lines)
    # reorder each polynomial from B to A so that reading it as A gives the B model back
    for poly in ("line_num", "line_den", "samp_num", "samp_den"):
        b = [float(getattr(ref, poly)[i]) for i in range(20)]
        for a_index, _ in enumerate(RPC00A_TO_B):
            text = text.replace(f"{poly}_coeff_{a_index:02d}:", f"@{poly}_{a_index}:")
        out = []
        for line in text.splitlines():
            for a_index, b_index in enumerate(RPC00A_TO_B):
                if line.startswith(f"@{poly}_{a_index}:"):
                    line = f"{poly}_coeff_{a_index:02d}:  {b[b_index]!r}"
            out.append(line)
        text = "\n".join(out)
    path = tmp_path / "a.geom"
    path.write_text(text + "\n")
    rpc, _, extra = read_rpc(path)
    assert extra["polynomial_format"] == "A"
    assert rpc == ref


# ------------------------------------------------------------------------------ vs GDAL
def _gdal_rpc(data_dir: Path, rel: str, ours: Rpc00b, gdal_readable: bool) -> RPC:
    if gdal_readable:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", NotGeoreferencedWarning)
            with rasterio.open(data_dir / rel) as ds:
                rpcs = ds.rpcs
        # GDAL's own parse; for GeoTIFF it reports the RPC tag as %.15g text while geoblock
        # reads the tag's doubles, hence 1e-14 rather than equality
        theirs = Rpc00b.from_gdal(rpcs.to_gdal()).to_dict()
        mine = ours.to_dict()
        for key, value in theirs.items():
            if key.startswith(("min_", "max_")):
                continue
            if value is None or mine[key] is None:
                assert value == mine[key], key
            else:
                np.testing.assert_allclose(mine[key], value, rtol=1e-14, atol=0, err_msg=key)
        return rpcs
    return RPC.from_gdal(ours.to_gdal())


def test_projection_equals_gdal_rpc_transformer(data_dir, rpc_file, rpc_files):
    rel = rpc_file
    model = _open(data_dir, rel)
    # files GDAL opens itself are also compared with GDAL's own parse
    rpc_gdal = _gdal_rpc(data_dir, rel, model.rpc, rpc_files[rel] in ("gdal", "gdal-vrt"))
    lon, lat, h = _random_ground(model.rpc, 10_000, seed=1, extent=1.0)
    (row, col), status = model.project_with_status(lon, lat, h)
    ok = status == 0
    assert ok.mean() > 0.95  # points outside a DIMAP validity box may be out of domain
    g_row, g_col = _gdal_project(rpc_gdal, lon[ok], lat[ok], h[ok])
    np.testing.assert_allclose(row[ok], g_row, rtol=0, atol=1e-6)
    np.testing.assert_allclose(col[ok], g_col, rtol=0, atol=1e-6)


# ------------------------------------------------------------------------------ crops
VENTOUX_GEOM = "shareloc/rpc/phr_ventoux/left_image.geom"
VENTOUX_TIF = "shareloc/image/phr_ventoux/left_image.tif"


def test_ventoux_crop_from_geotransform(data_dir):
    full = _open(data_dir, VENTOUX_GEOM)
    crop = _open(data_dir, VENTOUX_GEOM, image=data_dir / VENTOUX_TIF,
                 crop_from_geotransform=True)
    assert crop.shape == (500, 500)
    assert (crop.rpc.line_off, crop.rpc.samp_off) == (full.rpc.line_off - 5000,
                                                      full.rpc.samp_off - 5000)
    lon, lat = full.backproject(5250.0, 5100.0, 400.0)[:2]
    row, col = crop.project(lon, lat, 400.0)
    np.testing.assert_allclose([row, col], [250.0, 100.0], atol=1e-6)
    explicit = _open(data_dir, VENTOUX_GEOM, crop_offset=(5000, 5000))
    assert explicit.rpc == crop.rpc


def test_crop_refusals(data_dir):
    # the .geom is no raster: a geotransform needs image=
    with pytest.raises(ModelFormatError, match="image="):
        _open(data_dir, VENTOUX_GEOM, crop_from_geotransform=True)
    # the 178609 GeoTIFF's geotransform (0.5, 1, 0, -0.5, 0, -1) is no pixel-unit crop
    with pytest.raises(ModelFormatError, match="pixel-unit geotransform"):
        _open(data_dir, NICE_SOURCES[2], crop_from_geotransform=True)
    with pytest.raises(TypeError, match="unknown RPC reader option"):
        _open(data_dir, VENTOUX_GEOM, crop=(1, 2))


def test_crop_from_geotransform_of_written_gtiffs(tmp_path):
    """Core's open_image gives the crop offset; the identity geotransform (no offset for the
    core) stays the plugin's crop at (0, 0); a map geotransform is refused."""
    import warnings as _warnings

    from affine import Affine
    from geoblock_rpc import readers
    from geoblock_rpc.writers import write_gtiff

    assert "ReaderOptionError" in readers.__all__
    model = RpcModel.example()
    path = write_gtiff(model, tmp_path / "scene.tif")
    with _warnings.catch_warnings():
        _warnings.simplefilter("error")  # quiet opens: no NotGeoreferencedWarning
        rpc, shape, extra = read_rpc(path, crop_from_geotransform=True)
    assert extra["crop_offset"] == (0.0, 0.0) and rpc == read_rpc(path)[0]
    with rasterio.open(path, "r+") as ds:
        ds.transform = Affine(1, 0, 200, 0, 1, 100)
    rpc, shape, extra = read_rpc(path, crop_from_geotransform=True)
    assert extra["crop_offset"] == (100.0, 200.0) and shape == model.shape
    with rasterio.open(path, "r+") as ds:
        ds.transform = Affine(0.5, 0, 200, 0, -0.5, 100)
    with pytest.raises(ModelFormatError, match="pixel-unit geotransform"):
        read_rpc(path, crop_from_geotransform=True)

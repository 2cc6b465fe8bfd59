"""A full Pleiades scene with its DIMAP ``RPC_*.XML`` (issue 26, item 3).

The image's size is the DIMAP product document's (``DIM_*.XML`` ``Raster_Dimensions``), never
the RFM's validity domain (``Direct_Model_Validity_Domain``: rows -27..42248 for the 41801-row
Ventoux scene). An ``RPC_*.XML`` alone states no size: its model takes an image of about its
fitted extent as the whole scene. The full scene (41801 x 39182 px, as the OSSIM ``.geom`` and
the GML header of shareloc's crop say) is a VRT here: a stretched pattern with the real crop
pasted at its place (rows/cols 5000..5499).
"""

from __future__ import annotations

import shutil
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest
import rasterio
import rasterio.errors
from click.testing import CliRunner

import geoblock
from geoblock.errors import CropError
from geoblock.models.crop import model_for_image
from geoblock_rpc.model import RpcModel
from geoblock_rpc.readers import read_rpc

VENTOUX = "shareloc/rpc/phr_ventoux"
RPC_XML = f"{VENTOUX}/RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML"
GEOM = f"{VENTOUX}/left_image.geom"
CROP = "shareloc/image/phr_ventoux/left_image.tif"
DTM = "shareloc/dtm"
SCENE = (41801, 39182)  # the .geom's number_lines/number_samples, the crop's GML GridEnvelope


def _raster(path: Path, shape: tuple[int, int], sources: str = "") -> Path:
    """A VRT of ``shape`` px: a stretched 64 x 64 pattern, then ``sources`` on top."""
    pattern = path.parent / "pattern.tif"
    if not pattern.exists():
        y, x = np.mgrid[0:64, 0:64]
        data = (((x // 4 + y // 4) % 2) * 1000 + 7 * x + 13 * y + 1).astype("uint16")
        with warnings.catch_warnings():  # a VRT source needs no georeferencing
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            with rasterio.open(pattern, "w", driver="GTiff", width=64, height=64, count=1,
                               dtype="uint16") as ds:
                ds.write(data, 1)
    path.write_text(textwrap.dedent(f"""\
        <VRTDataset rasterXSize="{shape[1]}" rasterYSize="{shape[0]}">
          <VRTRasterBand dataType="UInt16" band="1">
            <SimpleSource>
              <SourceFilename relativeToVRT="1">pattern.tif</SourceFilename>
              <SourceBand>1</SourceBand>
              <SrcRect xOff="0" yOff="0" xSize="64" ySize="64"/>
              <DstRect xOff="0" yOff="0" xSize="{shape[1]}" ySize="{shape[0]}"/>
            </SimpleSource>{sources}
          </VRTRasterBand>
        </VRTDataset>
        """))
    return path


def _scene(tmp_path: Path, data_dir: Path) -> Path:
    crop = f"""
            <SimpleSource>
              <SourceFilename relativeToVRT="0">{data_dir / CROP}</SourceFilename>
              <SourceBand>1</SourceBand>
              <SrcRect xOff="0" yOff="0" xSize="500" ySize="500"/>
              <DstRect xOff="5000" yOff="5000" xSize="500" ySize="500"/>
            </SimpleSource>"""
    return _raster(tmp_path / "full.vrt", SCENE, crop)


def _dim(folder: Path, rpc_name: str, shape: tuple[int, int]) -> Path:
    """A DIMAP v2 product document naming ``rpc_name`` as its RFM component (the parts the
    reader reads: Raster_Dimensions and the Geoposition's COMPONENT_PATH)."""
    path = folder / "DIM_PHR1B_P_201308051042194_SEN_690908101-001.XML"
    path.write_text(textwrap.dedent(f"""\
        <?xml version="1.0" encoding="UTF-8"?>
        <Dimap_Document>
          <Metadata_Identification>
            <METADATA_FORMAT version="2.0">DIMAP</METADATA_FORMAT>
            <METADATA_PROFILE>PHR_SENSOR</METADATA_PROFILE>
          </Metadata_Identification>
          <Raster_Data><Raster_Dimensions>
            <NROWS>{shape[0]}</NROWS><NCOLS>{shape[1]}</NCOLS><NBANDS>1</NBANDS>
          </Raster_Dimensions></Raster_Data>
          <Geoposition><Geoposition_Models><Rational_Function_Model>
            <Component><COMPONENT_PATH href="{rpc_name}"/></Component>
          </Rational_Function_Model></Geoposition_Models></Geoposition>
        </Dimap_Document>
        """))
    return path


def test_the_rpc_file_alone_states_no_size(data_dir):
    """Before: the shape was the validity domain's LAST_ROW/LAST_COL, 42248 x 39208, stated."""
    rpc, shape, extra = read_rpc(data_dir / RPC_XML)
    assert shape is None and "shape_from" not in extra
    model = geoblock.open_model(data_dir / RPC_XML)
    assert isinstance(model, RpcModel) and not model.shape_stated
    assert model.shape == (42248, 39208)  # ceil(OFF + SCALE + 0.5): the fitted extent
    back = RpcModel.from_dict(model.to_dict())
    assert not back.shape_stated and back.shape == model.shape
    assert geoblock.open_model(data_dir / GEOM).shape_stated


def test_the_size_comes_from_the_dim_beside_it(data_dir, tmp_path):
    rpc_file = Path(shutil.copy(data_dir / RPC_XML, tmp_path))
    dim = _dim(tmp_path, rpc_file.name, SCENE)
    rpc, shape, extra = read_rpc(rpc_file)
    assert shape == SCENE and extra["shape_from"] == str(dim)
    model = geoblock.open_model(rpc_file)
    assert model.shape == SCENE and model.shape_stated
    # the product document itself: its size, the RPC component's coefficients
    rpc_dim, shape_dim, _ = read_rpc(dim)
    assert shape_dim == SCENE and rpc_dim.to_dict()["line_off"] == rpc.to_dict()["line_off"]
    # a DIM naming another RPC file is not this one's
    other = tmp_path / "other"
    other.mkdir()
    shutil.copy(rpc_file, other)
    _dim(other, "RPC_SOMETHING_ELSE.XML", (100, 100))
    assert read_rpc(other / rpc_file.name)[1] is None


def test_an_image_of_about_the_fitted_extent_is_the_whole_scene(data_dir, tmp_path):
    model = geoblock.open_model(data_dir / RPC_XML)
    full = model_for_image(model, _scene(tmp_path, data_dir))
    assert full.shape == SCENE and full.shape_stated
    assert full.rpc == model.rpc  # the pixels are the model's: no shift
    # a raster without crop information 15 % smaller than the fitted extent: a crop, refused
    small = _raster(tmp_path / "small.vrt", (35000, 33000))
    with pytest.raises(CropError, match="states no image size"):
        model_for_image(model, small)
    # a model whose file states its size keeps the strict rule
    with pytest.raises(CropError):
        model_for_image(geoblock.open_model(data_dir / GEOM), small)


def test_full_scene_ortho_with_the_rpc_xml_equals_the_geom(data_dir, tmp_path):
    """Same output grid and pixels from the DIMAP RPC and from the .geom (the issue's must-
    show), on a 200 x 200 m window over the real crop at 0.5 m, and equal to the ortho of the
    crop itself wherever the crop covers the window."""
    from geoblock.cli.main import build_cli

    scene = _scene(tmp_path, data_dir)
    dem = ["--dem", str(data_dir / DTM / "srtm_ventoux/srtm90_non_void_filled/N44E005.hgt"),
           "--geoid", str(data_dir / DTM / "geoid/egm96_15.gtx")]
    grid = ["--bounds", "675300", "4897200", "675500", "4897400", "--res", "0.5",
            "--crs", "EPSG:32631"]
    runner, cli = CliRunner(), build_cli()
    outputs = {}
    for name, image, model in (("rpc", scene, RPC_XML), ("geom", scene, GEOM),
                               ("crop", data_dir / CROP, GEOM)):
        out = tmp_path / f"{name}.tif"
        result = runner.invoke(cli, ["ortho", str(image), str(out), "--model",
                                     str(data_dir / model), *dem, *grid])
        assert result.exit_code == 0, result.output
        with rasterio.open(out) as ds:
            outputs[name] = (ds.transform, ds.crs, ds.read(1))
    if "taken as the whole scene" not in result.output:  # said on standard error
        assert "taken as the whole scene" in runner.invoke(
            cli, ["ortho", str(scene), str(tmp_path / "again.tif"), "--model",
                  str(data_dir / RPC_XML), *dem, *grid]).output
    (t_rpc, crs_rpc, rpc), (t_geom, crs_geom, geom) = outputs["rpc"], outputs["geom"]
    assert t_rpc == t_geom and crs_rpc == crs_geom and rpc.shape == geom.shape == (400, 400)
    assert np.array_equal(rpc, geom) and np.count_nonzero(geom) == geom.size
    crop = outputs["crop"][2]
    inside = crop != 0
    assert inside.sum() > 0.5 * crop.size and np.array_equal(crop[inside], geom[inside])

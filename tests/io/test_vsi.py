"""Sensor models from GDAL virtual paths (issue 25, item 8): /vsizip/, /vsimem/, /vsicurl/.

A virtual path is kept as given (pathlib would collapse its ``//``), its existence is checked
by GDAL, and the readers find sidecars beside an image inside an archive as on disk.
"""

from __future__ import annotations

import uuid
import zipfile
from pathlib import Path

import numpy as np
import pytest

import geoblock
from geoblock.errors import GeoblockIOError
from geoblock.io import open_quietly
from geoblock.io.metadata import read_bytes
from geoblock.io.vsi import VsiPath, as_path, exists, is_vsi

VENTOUX_LEFT = "shareloc/rpc/phr_ventoux/left_image.geom"
RPC_TIFF = "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif"


def _zip(tmp_path: Path, files: dict[str, Path]) -> Path:
    archive = tmp_path / "scene.zip"
    with zipfile.ZipFile(archive, "w") as z:
        for name, source in files.items():
            z.write(source, name)
    return archive


def _project(model: geoblock.SensorModel) -> np.ndarray:
    lon, lat, _ = model.backproject(100.0, 200.0, 500.0)
    return np.array([lon, lat])


def test_vsi_path_keeps_double_slashes() -> None:
    p = as_path("/vsicurl/https://example.com/scene/IMAGE.TIF")
    assert isinstance(p, VsiPath) and is_vsi(p)
    assert str(p.parent / "IMAGE.RPB") == "/vsicurl/https://example.com/scene/IMAGE.RPB"
    assert (p.name, p.stem, p.suffix) == ("IMAGE.TIF", "IMAGE", ".TIF")
    assert isinstance(as_path("scene/IMAGE.TIF"), Path) and not is_vsi("scene/IMAGE.TIF")


def test_geom_in_zip_opens_like_the_file(data_dir: Path, tmp_path: Path) -> None:
    archive = _zip(tmp_path, {"product/left_image.geom": data_dir / VENTOUX_LEFT})
    inside = f"/vsizip/{archive}/product/left_image.geom"
    assert exists(inside) and VsiPath(inside).parent.is_dir()
    assert read_bytes(inside) == (data_dir / VENTOUX_LEFT).read_bytes()
    assert read_bytes(inside, 5, 3) == (data_dir / VENTOUX_LEFT).read_bytes()[3:8]
    model = geoblock.open_model(inside)
    local = geoblock.open_model(data_dir / VENTOUX_LEFT)
    assert model.shape == local.shape
    np.testing.assert_allclose(_project(model), _project(local), rtol=0, atol=1e-12)


def test_rpc_tiff_in_zip_opens(data_dir: Path, tmp_path: Path) -> None:
    archive = _zip(tmp_path, {"image.tif": data_dir / RPC_TIFF})
    model = geoblock.open_model(f"/vsizip/{archive}/image.tif")
    local = geoblock.open_model(data_dir / RPC_TIFF)
    assert model.shape == local.shape == (128, 128)
    np.testing.assert_allclose(_project(model), _project(local), rtol=0, atol=1e-12)


def test_sidecar_beside_image_inside_zip(data_dir: Path, tmp_path: Path) -> None:
    """An image without RPC tags whose IMAGE_RPC.TXT sits beside it in the archive."""
    rpc_txt = data_dir / "gdal-autotest/gcore/data/test_rpc.txt"
    image = tmp_path / "IMAGE.TIF"
    with open_quietly(image, "w", driver="GTiff", width=64, height=48, count=1,
                       dtype="uint8") as ds:
        ds.write(np.zeros((1, 48, 64), np.uint8))
    archive = _zip(tmp_path, {"IMAGE.TIF": image, "IMAGE_RPC.TXT": rpc_txt})
    model = geoblock.open_model(f"/vsizip/{archive}/IMAGE.TIF")
    local = geoblock.open_model(rpc_txt)
    np.testing.assert_allclose(_project(model), _project(local), rtol=0, atol=1e-9)


def test_dg_sidecars_inside_zip(data_dir: Path, tmp_path: Path) -> None:
    """The DigitalGlobe .RPB found beside its .IMD inside an archive."""
    folder = data_dir / "gdal-autotest/gcore/data"
    archive = _zip(tmp_path, {"md_dg.RPB": folder / "md_dg.RPB",
                              "md_dg.IMD": folder / "md_dg.IMD"})
    model = geoblock.open_model(f"/vsizip/{archive}/md_dg.RPB")
    assert model.shape == geoblock.open_model(folder / "md_dg.RPB").shape


def test_geotiff_rpc_tags_in_vsimem(data_dir: Path) -> None:
    import rasterio
    import rasterio.shutil

    with rasterio.open(data_dir / RPC_TIFF) as src:
        rpcs, profile = src.rpcs, dict(src.profile)
    name = f"/vsimem/geoblock-{uuid.uuid4().hex}/image.tif"
    profile.update(driver="GTiff", width=32, height=16)
    try:
        with open_quietly(name, "w", rpcs=rpcs, **profile) as ds:
            ds.write(np.zeros((profile["count"], 16, 32), profile["dtype"]))
        model = geoblock.open_model(name)
        assert model.shape == (16, 32)
        local = geoblock.open_model(data_dir / RPC_TIFF)
        np.testing.assert_allclose(_project(model), _project(local), rtol=0, atol=1e-9)
    finally:
        rasterio.shutil.delete(name)


def test_missing_vsicurl_names_the_path_as_given() -> None:
    url = "/vsicurl/https://example.com/x.tif"
    with pytest.raises(GeoblockIOError) as info:
        geoblock.open_model(url)
    assert repr(url) in str(info.value) and "https:/example" not in str(info.value)


def test_missing_local_file_message_unchanged(tmp_path: Path) -> None:
    missing = tmp_path / "nope.geom"
    with pytest.raises(GeoblockIOError, match=r"^cannot open sensor model: '.*nope\.geom' "
                                              r"does not exist$"):
        geoblock.open_model(missing)


def test_missing_member_of_zip(data_dir: Path, tmp_path: Path) -> None:
    archive = _zip(tmp_path, {"left_image.geom": data_dir / VENTOUX_LEFT})
    inside = f"/vsizip/{archive}/other.geom"
    with pytest.raises(GeoblockIOError, match="does not exist"):
        geoblock.open_model(inside)
    with pytest.raises(GeoblockIOError, match="cannot read"):
        read_bytes(inside)

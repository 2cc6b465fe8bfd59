"""A model of another image is refused by model_for_image (issue 25, item 9).

Only ids of the same kind on both sides are compared; file names never are.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import geoblock
from geoblock.errors import ModelImageMismatchError
from geoblock.io import open_image, open_quietly
from geoblock.models.crop import CroppedModel, model_for_image

WV_LEFT = "stereopipeline/tests/wv_test1.xml"  # CATID 1030010021309100
WV_RIGHT = "stereopipeline/tests/wv_test2.xml"  # CATID 1030010022D83700, same product id


@pytest.fixture()
def dg_image(data_dir: Path, tmp_path: Path) -> Path:
    """A small GeoTIFF with the left WorldView image's ISD beside it (GDAL's IMD domain)."""
    image = tmp_path / "left.tif"
    with open_quietly(image, "w", driver="GTiff", width=40, height=30, count=1,
                      dtype="uint8") as ds:
        ds.write(np.zeros((1, 30, 40), np.uint8))
    shutil.copy(data_dir / WV_LEFT, tmp_path / "left.XML")
    return image


def test_raster_ids(dg_image: Path, data_dir: Path) -> None:
    assert dict(open_image(dg_image).source_ids) == {"catalog_id": "1030010021309100"}
    crop = open_image(data_dir / "shareloc/image/phr_ventoux/left_image.tif")
    assert dict(crop.source_ids) == {
        "datastrip_id": "DS_PHR1B_201308051041444_FR1_PX_E005N44_0404_01878"}


def test_model_of_the_other_image_is_refused(dg_image: Path, data_dir: Path) -> None:
    right = geoblock.open_model(data_dir / WV_RIGHT, model="rpc")
    assert right.source_ids == {"catalog_id": "1030010022D83700"}
    with pytest.raises(ModelImageMismatchError) as info:
        model_for_image(right, dg_image, crop_offset=(0, 0))
    message = str(info.value)
    for part in ("1030010022D83700", "1030010021309100", str(dg_image), WV_RIGHT,
                 "force=True"):
        assert part in message
    # a correction or a crop of it keeps the ids, so is refused too
    with pytest.raises(ModelImageMismatchError):
        model_for_image(geoblock.ImageCorrection(right, 0), dg_image, crop=False)
    # the CLI's spelling
    with pytest.raises(ModelImageMismatchError, match="--force"):
        model_for_image(right, dg_image, crop=False, names={"force": "--force"})


def test_force_accepts(dg_image: Path, data_dir: Path) -> None:
    right = geoblock.open_model(data_dir / WV_RIGHT, model="rpc")
    out = model_for_image(right, dg_image, crop_offset=(0, 0), force=True)
    assert isinstance(out, CroppedModel) and out.shape == (30, 40)
    assert model_for_image(right, dg_image, crop=False, force=True) is right


def test_model_of_the_same_image_passes(dg_image: Path, data_dir: Path) -> None:
    left = geoblock.open_model(data_dir / WV_LEFT, model="rpc")
    out = model_for_image(left, dg_image, crop_offset=(0, 0))
    assert out.shape == (30, 40) and out.source_ids == {"catalog_id": "1030010021309100"}


def test_ids_of_different_kinds_never_refuse(data_dir: Path) -> None:
    """The Ventoux crop names its datastrip, the .geom its OSSIM image id: no evidence."""
    geom = geoblock.open_model(data_dir / "shareloc/rpc/phr_ventoux/right_image.geom")
    assert geom.source_ids == {"ossim_image_id": "690908101-002"}
    model_for_image(geom, data_dir / "shareloc/image/phr_ventoux/left_image.tif")


#: every image/model pair of the shared data that belongs together
PAIRS = [
    ("shareloc/image/phr_ventoux/left_image.tif", "shareloc/rpc/phr_ventoux/left_image.geom"),
    ("shareloc/image/phr_ventoux/left_image.tif", "shareloc/rectification/left_image.geom"),
    ("shareloc/image/phr_ventoux/left_image.tif",
     "shareloc/rpc/phr_ventoux/RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML"),
    ("shareloc/image/phr_ventoux/right_image.tif", "shareloc/rpc/phr_ventoux/right_image.geom"),
    ("shareloc/image/phr_ventoux/right_image.tif", "shareloc/rectification/right_image.geom"),
    ("shareloc/image/phr_ventoux/right_image.tif",
     "shareloc/rpc/phr_ventoux/right_image_bias.geom"),
    ("shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif",
     "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif"),
    ("shareloc/rpc/wv3_20.NTF", "shareloc/rpc/wv3_20.NTF"),
    ("shareloc/rpc/wv3_30.NTF", "shareloc/rpc/wv3_30.NTF"),
]


@pytest.mark.parametrize(("image", "model"), PAIRS, ids=[Path(m).name for _, m in PAIRS])
def test_real_pairs_pass(data_dir: Path, image: str, model: str) -> None:
    opened = geoblock.open_model(data_dir / model)
    out = model_for_image(opened, data_dir / image, crop=False)
    assert out is opened

"""Fixtures of the geoblock-rpc tests (self-contained: the tests run with --import-mode=importlib).

Real data lives in ``<repo>/../shared/data``; ``GEOBLOCK_TEST_DATA`` overrides it. Tests that
need it skip with the reason when it is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
DATA_DIR = Path(os.environ.get("GEOBLOCK_TEST_DATA", REPO.parent / "shared" / "data"))


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """The shared real-data folder (skips the test when it is absent)."""
    if not DATA_DIR.is_dir():
        pytest.skip(f"real test data not found at {DATA_DIR} (set GEOBLOCK_TEST_DATA)")
    return DATA_DIR


#: relative path -> format the reader reports
RPC_FILES = {
    "gdal-autotest/extracted/transformer_11_rpc.vrt": "gdal-vrt",
    "gdal-autotest/extracted/transformer_15_rpc.vrt": "gdal-vrt",
    "gdal-autotest/gcore/data/md_dg.RPB": "rpb",
    "gdal-autotest/gcore/data/rpc.vrt": "gdal-vrt",
    "gdal-autotest/gcore/data/rpc_5395.vrt": "gdal-vrt",
    "gdal-autotest/gcore/data/test_rpc.txt": "rpc-txt",
    "rpcm/test_rpc_files/20191015_073816_ssc1d3_0011_basic_l1a_panchromatic_dn_RPC.TXT": "rpc-txt",
    "rpcm/test_rpc_files/JAX_068_001_RGB.json": "rpcm-json",
    "rpcm/test_rpc_files/rpc_IKONOS.txt": "rpc-txt",
    "rpcm/test_rpc_files/rpc_PLANET_L1A.txt": "rpc-txt",
    "rpcm/test_rpc_files/rpc_PLANET_L1B.txt": "rpc-txt",
    "rpcm/test_rpc_files/rpc_PLEIADES.xml": "dimap-v2",
    "rpcm/test_rpc_files/rpc_SPOT6.xml": "dimap-v2",
    "rpcm/test_rpc_files/rpc_WV1.xml": "dg-isd",
    "rpcm/test_rpc_files/rpc_WV2.xml": "dg-isd",
    "rpcm/test_rpc_files/rpc_WV3.xml": "dg-isd",
    # rpcm refuses it, but it is a valid GDAL VRT with a complete RPC domain (GDAL opens it)
    "rpcm/test_rpc_files/rpc_unsupported.xml": "gdal-vrt",
    "shareloc/rectification/left_image.geom": "ossim-kwl",
    "shareloc/rectification/right_image.geom": "ossim-kwl",
    "shareloc/rpc/PHR1B_P_201709281038045_SEN_PRG_FC_178608-001.geom": "ossim-kwl",
    "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.geom": "ossim-kwl",
    "shareloc/rpc/PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.tif": "gdal",
    "shareloc/rpc/PHRDIMAP_P1BP--2017030824934340CP.XML": "dimap-phr",
    "shareloc/rpc/PHRDIMAP_P1BP--2018122638935449CP.XML": "dimap-phr",
    "shareloc/rpc/RPC_P1BP--2017092838284574CP.XML": "dimap-v2",
    "shareloc/rpc/RPC_P1BP--2017092838319324CP.XML": "dimap-v2",
    "shareloc/rpc/RPC_PHR1B_P_201709281038045_SEN_PRG_FC_178608-001.XML": "dimap-v2",
    "shareloc/rpc/RPC_PHR1B_P_201709281038393_SEN_PRG_FC_178609-001.XML": "dimap-v2",
    "shareloc/rpc/phr_gizeh/img1.geom": "ossim-kwl",
    "shareloc/rpc/phr_gizeh/img2.geom": "ossim-kwl",
    "shareloc/rpc/phr_oise/RPC_PHR1A_P_202503191043438_SEN_7342362101-1.XML": "dimap-v2",
    "shareloc/rpc/phr_ventoux/RPC_PHR1B_P_201308051042194_SEN_690908101-001.XML": "dimap-v2",
    "shareloc/rpc/phr_ventoux/left_image.geom": "ossim-kwl",
    "shareloc/rpc/phr_ventoux/lowres_color_image.geom": "ossim-kwl",
    "shareloc/rpc/phr_ventoux/right_image.geom": "ossim-kwl",
    "shareloc/rpc/phr_ventoux/right_image_bias.geom": "ossim-kwl",
    "shareloc/rpc/wv3_20.NTF": "gdal",
    "shareloc/rpc/wv3_30.NTF": "gdal",
    "stereopipeline/tests/dg_example1.xml": "dg-isd",
    "stereopipeline/tests/dg_example3.xml": "dg-isd",
    "stereopipeline/tests/sample.RPB": "rpb",
    "stereopipeline/tests/wv_test1.xml": "dg-isd",
    "stereopipeline/tests/wv_test2.xml": "dg-isd",
}


def pytest_generate_tests(metafunc):
    """``rpc_file``: every RPC-carrying file of the shared data, one test each."""
    if "rpc_file" in metafunc.fixturenames:
        metafunc.parametrize("rpc_file", sorted(RPC_FILES))


@pytest.fixture(scope="session")
def rpc_files() -> dict[str, str]:
    """Relative path -> format the reader reports, for every RPC file of the shared data."""
    return dict(RPC_FILES)

"""Named parameter sets of the SPOT models: Chen & Lee's ``coefficients``/``mba`` and the DIMAP
readers' ``dg`` through the sensor-model protocol's ``with_parameter_set``."""

from __future__ import annotations

import json

import numpy as np
import pytest
from geoblock_spot import los
from geoblock_spot.chenlee import ChenLeeModel
from geoblock_spot.dimap import read_dimap
from geoblock_spot.dimap2 import dimap2_model
from geoblock_spot.los import spot_dimap_model

from geoblock.errors import ParameterSetError
from geoblock.models import linescan
from geoblock.testing.checks import check_parameter_sets

SPOT5 = "cosicorr3d/test_dataset/SPOT5.DIM"
PHR_2018 = "shareloc/rpc/PHRDIMAP_P1BP--2018122638935449CP.XML"


@pytest.fixture(scope="module")
def table1():
    return ChenLeeModel.table1()


# ============================================================================ Chen & Lee
def test_chenlee_lists_its_sets(table1):
    assert ChenLeeModel.parameter_sets == ("default", "coefficients", "mba")
    assert table1.with_parameter_set("default") is table1


def test_chenlee_mba_set_equals_mba(table1):
    mba = table1.with_parameter_set("mba", accuracy_m=350.0)
    assert mba == table1.mba(350.0) and mba.parameter_set == "mba"
    assert table1.with_parameter_set("mba", location_accuracy_m=350.0) == mba  # the alias
    np.testing.assert_array_equal(mba.parameters.sigmas, table1.mba_sigmas(350.0))


def test_chenlee_mba_uses_the_stored_accuracy(table1):
    with pytest.raises(ParameterSetError, match="accuracy_m"):
        table1.with_parameter_set("mba")
    stored = ChenLeeModel.table1(location_accuracy_m=50.0)
    assert stored.location_accuracy_m == 50.0
    mba = stored.with_parameter_set("mba")
    np.testing.assert_array_equal(mba.parameters.sigmas, table1.mba_sigmas(50.0))
    assert mba.location_accuracy_m == 50.0
    assert stored.with_parameters(stored.parameters.values).location_accuracy_m == 50.0
    # "coefficients" stays free unless asked otherwise
    assert np.all(np.isinf(stored.with_parameter_set("coefficients").parameters.sigmas))


def test_chenlee_sets_keep_the_geometry(table1):
    moved = table1.mba(350.0).with_parameters(np.linspace(-1e-6, 1e-6, 19))
    g = table1.backproject([10.0, 5000.0], [20.0, 4000.0], [0.0, 900.0])
    for name, opts in (("coefficients", {}), ("mba", {"accuracy_m": 50.0})):
        other = moved.with_parameter_set(name, **opts)
        np.testing.assert_allclose(np.stack(other.project(g.lon, g.lat, g.h)),
                                   np.stack(moved.project(g.lon, g.lat, g.h)), atol=1e-9)


def test_chenlee_refuses_bad_requests(table1):
    with pytest.raises(ParameterSetError, match=r"'dg'.*\['default', 'coefficients', 'mba'\]"):
        table1.with_parameter_set("dg")
    with pytest.raises(ParameterSetError, match="bogus"):
        table1.with_parameter_set("mba", accuracy_m=350.0, bogus=1)
    with pytest.raises(ParameterSetError, match="not both"):
        table1.with_parameter_set("mba", accuracy_m=350.0, sigmas=table1.mba_sigmas(350.0))
    with pytest.raises(ParameterSetError, match="not both"):
        table1.with_parameter_set("mba", accuracy_m=350.0, location_accuracy_m=350.0)
    with pytest.raises(ParameterSetError, match="location_accuracy_m"):
        table1.mba(0.0)


def test_chenlee_json_records_the_accuracy_only_when_known(table1):
    assert "location_accuracy_m" not in table1.mba(350.0).to_dict()
    stored = ChenLeeModel.table1(location_accuracy_m=350.0).mba(350.0)
    data = json.loads(json.dumps(stored.to_dict()))
    assert data["location_accuracy_m"] == 350.0
    assert ChenLeeModel.from_dict(data) == stored


def test_chenlee_passes_the_parameter_set_check(table1):
    assert check_parameter_sets(table1, parameter_set_options={"mba": {"accuracy_m": 350.0}}) == {}
    assert check_parameter_sets(ChenLeeModel.table1(location_accuracy_m=350.0).mba(50.0)) == {}
    assert list(check_parameter_sets(table1)) == ["mba"]


# ============================================================================ DIMAP readers
def test_dg_moved_to_the_core():
    assert los.dg_parameters is linescan.dg_parameters
    assert los.DG_ADJUSTABLE is linescan.DG_ADJUSTABLE


def test_spot_dimap_dg_is_the_models_dg_set(data_dir):
    dimap = read_dimap(data_dir / SPOT5)
    free = spot_dimap_model(dimap, parameters="linescan")
    assert free.location_accuracy_m == dimap.location_accuracy_m
    dg = spot_dimap_model(dimap)
    assert dg == free.with_parameter_set("dg")
    assert dg.parameters == linescan.dg_parameters(free, dimap.location_accuracy_m)
    assert check_parameter_sets(free) == {}


def test_dimap2_stores_the_given_accuracy(data_dir):
    path = data_dir / PHR_2018
    free = dimap2_model(path, accuracy_m=5.0)
    assert free.location_accuracy_m == 5.0 and np.all(np.isinf(free.parameters.sigmas))
    assert dimap2_model(path, parameters="dg", accuracy_m=5.0) == free.with_parameter_set("dg")
    assert dimap2_model(path).location_accuracy_m is None
    with pytest.raises(ParameterSetError, match="accuracy_m"):
        dimap2_model(path, parameters="dg")

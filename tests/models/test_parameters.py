import json

import numpy as np
import pytest

from geoblock import ParameterSet
from geoblock.errors import SerializationError


def make():
    return ParameterSet(("a0", "b0"), [1.0, 2.0], ("px", "px"), [0.5, np.inf])


def test_immutable_and_with_values():
    p = make()
    with pytest.raises(ValueError):
        p.values[0] = 3.0
    q = p.with_values({"b0": 5.0})
    assert p["b0"] == 2.0 and q["b0"] == 5.0
    assert q.sigmas[0] == 0.5 and np.isinf(q.sigmas[1])
    with pytest.raises(ValueError, match=r"expected 2 values \['a0', 'b0'\]"):
        p.with_values([1.0])
    with pytest.raises(KeyError, match="no parameter 'c0'"):
        p.with_values({"c0": 1.0})


def test_json_round_trip_with_free_parameters():
    p = make().with_adjustable(["a0"])
    text = json.dumps(p.to_dict(), allow_nan=False)
    q = ParameterSet.from_dict(json.loads(text))
    assert q == p and list(q.adjustable) == [True, False]
    assert np.allclose(q.prior_covariance, np.diag([0.25, np.inf]))


def test_covariance():
    cov = [[0.25, 0.1], [0.1, 1.0]]
    p = ParameterSet(("a", "b"), [0, 0], covariance=cov)
    assert np.allclose(p.sigmas, [0.5, 1.0])
    with pytest.raises(ValueError, match="symmetric"):
        ParameterSet(("a", "b"), [0, 0], covariance=[[1, 0.1], [0, 1]])


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"names": ("a", "a"), "values": [0, 0]}, "duplicate"),
        ({"names": ("a",), "values": [0, 0]}, "values of shape"),
        ({"names": ("a",), "values": [0], "sigmas": [0.0]}, "sigmas must be > 0"),
    ],
)
def test_invalid(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ParameterSet(**kwargs)


def test_from_dict_errors():
    with pytest.raises(SerializationError, match="invalid parameter set"):
        ParameterSet.from_dict({"names": ["a"]})


def test_location_accuracy_helper():
    from geoblock.errors import ModelFormatError, ParameterSetError
    from geoblock.models.parameters import accuracy_or_stored, location_accuracy

    assert location_accuracy("2.5", "x") == 2.5 and location_accuracy(3, "x") == 3.0
    for bad in (0.0, -1.0, float("nan"), float("inf"), "ten", None, [1.0]):
        with pytest.raises(ModelFormatError, match=r"^where: must be finite and > 0"):
            location_accuracy(bad, "where")
    with pytest.raises(ParameterSetError):
        location_accuracy(0.0, "where", ParameterSetError)
    assert accuracy_or_stored(5.0, 12.0, "M", "dg") == 5.0
    assert accuracy_or_stored(None, 12.0, "M", "dg") == 12.0
    with pytest.raises(ParameterSetError, match=r"M: parameter set 'dg'.*pass sigmas="):
        accuracy_or_stored(None, None, "M", "dg", advice="sigmas=")
    with pytest.raises(ParameterSetError, match=r"M, parameter set 'dg': accuracy_m"):
        accuracy_or_stored(-1.0, 12.0, "M", "dg")

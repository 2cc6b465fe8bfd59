"""The conformance kit rejects deliberately broken models, saying what is wrong.

Each broken model is a synthetic model with one realistic mistake; the kit must fail the
relevant check with a message naming the problem, and the healthy originals must pass.
"""

from __future__ import annotations

import json
import math
from typing import Any, ClassVar

import numpy as np
import pytest

from geoblock.models import SensorModelBase
from geoblock.testing import checks
from geoblock.testing.checks import (
    CHECKS,
    check_dask_token,
    check_footprint,
    check_ground_partials,
    check_nan_isolation,
    check_no_mutation,
    check_parameter_partials,
    check_parameter_perturbation,
    check_pickle,
    check_round_trip,
    check_sensor_model,
    check_serialization,
    check_shapes,
    check_with_parameters,
)
from geoblock.testing.contract import SensorModelContract
from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom
from geoblock.typing import GroundCoords, ImageCoords, Status


def affine(cls: type = AffineCamera, **kwargs: Any) -> Any:
    base = AffineCamera.example()
    return cls(base.shape, base._origin, base.coefficients, base.height_range, **kwargs)


def pushbroom(cls: type = ConstantVelocityPushbroom) -> Any:
    base = ConstantVelocityPushbroom.example(roll=0.01)
    return cls.from_dict(base.to_dict())


# ============================================================= broken partials
class FlippedGroundPartials(AffineCamera):
    name: ClassVar[str] = "broken-flipped-ground"

    def partials_ground(self, lon, lat, h):
        return -super().partials_ground(lon, lat, h)


class SwappedGroundPartials(AffineCamera):
    name: ClassVar[str] = "broken-swapped-ground"

    def partials_ground(self, lon, lat, h):
        return super().partials_ground(lon, lat, h)[..., ::-1, :].copy()


class EnuGroundPartials(AffineCamera):
    """Forgets to chain the local east/north/up partials to ECEF."""

    name: ClassVar[str] = "broken-enu-ground"

    def partials_ground(self, lon, lat, h):
        lon, lat, h = np.broadcast_arrays(*(np.asarray(v, float) for v in (lon, lat, h)))
        return np.broadcast_to(self.coefficients[:, 1:], lon.shape + (2, 3)).copy()


class TransposedGroundPartials(AffineCamera):
    name: ClassVar[str] = "broken-transposed-ground"

    def partials_ground(self, lon, lat, h):
        return np.swapaxes(super().partials_ground(lon, lat, h), -1, -2)


class FlippedRollPartial(ConstantVelocityPushbroom):
    name: ClassVar[str] = "broken-flipped-roll"

    def partials_parameters(self, lon, lat, h):
        out = super().partials_parameters(lon, lat, h)
        out[..., 0] *= -1.0
        return out


class DegreesPartials(ConstantVelocityPushbroom):
    """Partials per degree while the parameters are in radians."""

    name: ClassVar[str] = "broken-degrees"

    def partials_parameters(self, lon, lat, h):
        return super().partials_parameters(lon, lat, h) * (math.pi / 180.0)


class ZeroColumn(AffineCamera):
    name: ClassVar[str] = "broken-zero-column"

    def partials_parameters(self, lon, lat, h):
        out = super().partials_parameters(lon, lat, h)
        out[..., 7] = 0.0  # col_u
        return out


@pytest.mark.parametrize(
    ("cls", "match"),
    [
        (FlippedGroundPartials, r"d (row|col)/d [xyz](.|\n)*sign is flipped"),
        (SwappedGroundPartials, r"row and col partials are swapped"),
        (EnuGroundPartials, r"east/north/up(.|\n)*ECEF"),
        (TransposedGroundPartials,
         r"wrong shape(.|\n)*shape \(36, 2, 3\)(.|\n)*shape \(36, 3, 2\)"),
    ],
)
def test_wrong_ground_partials(cls, match):
    with pytest.raises(AssertionError, match=match) as info:
        check_ground_partials(affine(cls), n=3)
    assert "check_ground_partials failed" in str(info.value)


def test_wrong_ground_partials_message_shows_point_and_values():
    with pytest.raises(AssertionError) as info:
        check_ground_partials(affine(FlippedGroundPartials), n=3)
    text = str(info.value)
    for piece in ("at:", "lon=", "lat=", "expected:", "(numeric)", "got:", "(partials_ground)",
                  "hint:"):
        assert piece in text, text


def test_wrong_parameter_partials_sign():
    model = pushbroom(FlippedRollPartial)
    with pytest.raises(AssertionError, match=r"d (row|col)/d roll(.|\n)*sign of the 'roll' column"):
        check_parameter_partials(model, n=3)
    with pytest.raises(AssertionError, match=r"'roll'(.|\n)*wrong sign"):
        check_parameter_perturbation(model)


def test_parameter_partials_in_wrong_unit():
    model = pushbroom(DegreesPartials)
    with pytest.raises(AssertionError, match=r"constant factor 0\.01745(.|\n)*degrees vs radians"):
        check_parameter_partials(model, n=3)
    with pytest.raises(AssertionError, match=r"wrong size"):
        check_parameter_perturbation(model)


def test_zero_parameter_partial():
    model = affine(ZeroColumn)
    with pytest.raises(AssertionError, match=r"d col/d col_u(.|\n)*'col_u' column is zero"):
        check_parameter_partials(model, n=3)
    with pytest.raises(AssertionError, match=r"partials_parameters is zero for 'col_u'"):
        check_parameter_perturbation(model)


# ============================================================= round trip
class HalfPixelPushbroom(ConstantVelocityPushbroom):
    """project uses the pixel-corner convention; backproject the pixel-centre one."""

    name: ClassVar[str] = "broken-half-pixel"

    def ground_to_image(self, lon, lat, h):
        row, col, status = super().ground_to_image(lon, lat, h)
        return row + 0.5, col + 0.5, status


class SloppyInverse(AffineCamera):
    """A backprojection that stops iterating too early."""

    name: ClassVar[str] = "broken-sloppy-inverse"
    newton_tolerance_px: ClassVar[float] = 1e-9

    def image_to_ground(self, row, col, h):
        lon, lat, status = self._newton_image_to_ground(row + 1e-4, col, h)
        return lon, lat, status


def test_half_pixel_offset_between_project_and_backproject():
    with pytest.raises(AssertionError,
                       match=r"misses \(row, col\) by 0\.70\d+ px(.|\n)*half-pixel"):
        check_round_trip(pushbroom(HalfPixelPushbroom), n=3)


def test_small_inverse_error_is_caught():
    with pytest.raises(AssertionError, match=r"misses(.|\n)*1e-06 px(.|\n)*stops too early"):
        check_round_trip(affine(SloppyInverse), n=3)


# ============================================================= serialisation
class LossyToDict(ConstantVelocityPushbroom):
    """to_dict() loses the roll value."""

    name: ClassVar[str] = "broken-lossy"

    def to_dict(self):
        data = super().to_dict()
        data["parameters"]["values"][0] = 0.0
        return data


class NumpyToDict(AffineCamera):
    name: ClassVar[str] = "broken-numpy-dict"

    def to_dict(self):
        data = super().to_dict()
        data["origin"] = np.array(data["origin"])
        return data


class WrongModelField(AffineCamera):
    """Copy-pasted to_dict() that names the model it was copied from."""

    name: ClassVar[str] = "broken-model-field"

    def to_dict(self):
        return {**super().to_dict(), "model": "synthetic-affine"}


class RandomToken(AffineCamera):
    name: ClassVar[str] = "broken-random-token"
    _counter: ClassVar[list[int]] = [0]

    def __dask_tokenize__(self):
        self._counter[0] += 1
        return self._counter[0]


def test_to_dict_that_loses_state():
    model = pushbroom(LossyToDict)
    with pytest.raises(AssertionError, match=r"projects differently(.|\n)*every parameter value"):
        check_serialization(model)
    with pytest.raises(AssertionError, match=r"projects differently"):
        check_pickle(model)
    with pytest.raises(AssertionError, match=r"'roll' changed(.|\n)*is == the original"):
        check_with_parameters(model)
    with pytest.raises(AssertionError,
                       match=r"changed parameters \(.roll. \+ 1e-07\) has the same dask token"):
        check_dask_token(model)


def test_to_dict_with_numpy_values():
    with pytest.raises(AssertionError,
                       match=r"not JSON-safe(.|\n)*to_dict\(\)\['origin'\] is a numpy"):
        check_serialization(affine(NumpyToDict))


def test_to_dict_naming_another_model():
    with pytest.raises(AssertionError, match=r"\['model'\] is not the model's name"):
        check_serialization(affine(WrongModelField))


def test_unstable_dask_token():
    with pytest.raises(AssertionError, match=r"tokenize\(model\) changes between calls"):
        check_dask_token(affine(RandomToken))


# ============================================================= with_parameters, mutation
class ForgetfulWithParameters(AffineCamera):
    """with_parameters drops the a-priori sigmas."""

    name: ClassVar[str] = "broken-forgetful"

    def with_parameters(self, values):
        return type(self)(self.shape, self._origin, values, self.height_range)


class CountingAffine(AffineCamera):
    """project() increments a counter that to_dict() records."""

    name: ClassVar[str] = "broken-counting"

    def __init__(self, *args, calls: int = 0, **kwargs):
        super().__init__(*args, **kwargs)
        self._calls = calls

    def project(self, lon, lat, h):
        self._calls += 1
        return super().project(lon, lat, h)

    def to_dict(self):
        return {**super().to_dict(), "calls": self._calls}


class InPlaceRadians(AffineCamera):
    """Converts the caller's arrays to radians in place."""

    name: ClassVar[str] = "broken-in-place"

    def project(self, lon, lat, h):
        lon, lat = np.asarray(lon), np.asarray(lat)
        if lon.ndim and lon.dtype == np.float64:
            np.radians(lon, out=lon)
            np.radians(lat, out=lat)
            return super().project(np.degrees(lon), np.degrees(lat), h)
        return super().project(lon, lat, h)


class AliasedToDict(AffineCamera):
    """to_dict() hands out its internal dictionary."""

    name: ClassVar[str] = "broken-aliased"

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._state = super().to_dict()

    def to_dict(self):
        return self._state


def test_with_parameters_losing_sigmas():
    model = affine(ForgetfulWithParameters, sigmas=np.full(8, 0.5))
    with pytest.raises(AssertionError,
                       match=r"with_parameters\(parameters\.values\) changes parameters\.sigmas"):
        check_with_parameters(model)


def test_model_that_mutates_itself():
    model = affine(CountingAffine)
    with pytest.raises(AssertionError, match=r"calling project\(lon, lat, h\) changed the model"
                       r"(.|\n)*'calls': 0 -> 1"):
        check_no_mutation(model)


def test_model_that_modifies_its_inputs():
    with pytest.raises(AssertionError, match=r"project\(lon, lat, h\) modified its first input"):
        check_no_mutation(affine(InPlaceRadians))


def test_to_dict_returning_internal_state():
    with pytest.raises(AssertionError, match=r"editing the dictionary returned by to_dict"):
        check_no_mutation(affine(AliasedToDict))


# ============================================================= NaN and shapes
class LeakyNaN(AffineCamera):
    """'Centres' the image coordinates with a statistic over all points: one NaN spoils all."""

    name: ClassVar[str] = "broken-leaky"

    def project_with_status(self, lon, lat, h):
        (row, col), status = super().project_with_status(lon, lat, h)
        shift = 0.0 * np.mean(np.asarray(lon, dtype=np.float64))
        return ImageCoords(row + shift, col + shift), status


class ConvergedNaN(AffineCamera):
    name: ClassVar[str] = "broken-status"

    def project_with_status(self, lon, lat, h):
        coords_, status = super().project_with_status(lon, lat, h)
        return coords_, np.zeros_like(status)


class OneDimScalars(AffineCamera):
    name: ClassVar[str] = "broken-scalar-shape"

    def project(self, lon, lat, h):
        row, col = super().project(lon, lat, h)
        return ImageCoords(np.atleast_1d(row), np.atleast_1d(col))


class Float32Output(ConstantVelocityPushbroom):
    name: ClassVar[str] = "broken-float32"

    def backproject(self, row, col, h):
        ground = super().backproject(row, col, h)
        return GroundCoords(*(np.asarray(a, dtype=np.float32) for a in ground))


class PlainTupleOutput(AffineCamera):
    name: ClassVar[str] = "broken-plain-tuple"

    def project(self, lon, lat, h):
        return tuple(super().project(lon, lat, h))


class PairwisePartials(AffineCamera):
    """Ignores broadcasting in its partials."""

    name: ClassVar[str] = "broken-broadcast"

    def partials_parameters(self, lon, lat, h):
        lon, lat, h = (np.asarray(v, dtype=np.float64) for v in (lon, lat, h))
        if lon.ndim == 2 and lon.shape != lat.shape:
            lon, lat = np.broadcast_arrays(lon, lat.T.ravel()[: lon.shape[0]].reshape(-1, 1))
            lon, lat = np.broadcast_to(lon, (3, 4)), np.broadcast_to(lat, (3, 4))
        return super().partials_parameters(lon, lat, h)


def test_nan_leaking_across_points():
    with pytest.raises(AssertionError,
                       match=r"non-finite input at point\(s\) \[1, 3, 4\] changes row "
                       r"at 3 other point\(s\)(.|\n)*must not leak"):
        check_nan_isolation(affine(LeakyNaN))


def test_non_finite_input_without_invalid_status():
    with pytest.raises(AssertionError, match=r"wrong status(.|\n)*INVALID_INPUT"):
        check_nan_isolation(affine(ConvergedNaN))


def test_scalar_input_giving_1d_output():
    with pytest.raises(AssertionError, match=r"project\(python floats\)\.row has the wrong shape"
                       r"(.|\n)*expected: shape \(\) float64(.|\n)*got: +shape \(1,\)"):
        check_shapes(affine(OneDimScalars))


def test_float32_output():
    with pytest.raises(AssertionError, match=r"backproject\(python floats\)\.lon(.|\n)*float64"
                       r"(.|\n)*float32"):
        check_shapes(pushbroom(Float32Output))


def test_plain_tuple_output():
    with pytest.raises(AssertionError, match=r"does not return a named tuple \(row, col\)"):
        check_shapes(affine(PlainTupleOutput))


def test_broadcasting_done_wrong():
    with pytest.raises(AssertionError, match=r"partials_parameters\(lon \(3, 1\), lat \(1, 4\)"
                       r"(.|\n)*differs from the same points"):
        check_shapes(affine(PairwisePartials))


# ============================================================= footprint
class CentreFootprint(AffineCamera):
    """Footprint through the centres of the border pixels instead of their outer edges."""

    name: ClassVar[str] = "broken-footprint"

    def footprint(self, h=None, n=16):
        rows, cols = self.shape
        h = 0.5 * sum(self.height_range) if h is None else h
        t = np.linspace(0.0, 1.0, n, endpoint=False)
        r0, r1, c0, c1 = 0.0, rows - 1.0, 0.0, cols - 1.0
        row = np.concatenate(
            [np.full(n, r0), r0 + (r1 - r0) * t, np.full(n, r1), r1 - (r1 - r0) * t])
        col = np.concatenate(
            [c0 + (c1 - c0) * t, np.full(n, c1), c1 - (c1 - c0) * t, np.full(n, c0)])
        return self.backproject(row, col, np.full(row.shape, float(h)))


class NarrowDomain(AffineCamera):
    """Refuses points beyond the outer pixel centres (the pixel edges are part of the image)."""

    name: ClassVar[str] = "broken-domain"

    def ground_to_image(self, lon, lat, h):
        row, col = super().ground_to_image(lon, lat, h)
        rows, cols = self.shape
        outside = (row < -1e-3) | (col < -1e-3) | (row > rows - 1 + 1e-3) | (col > cols - 1 + 1e-3)
        return row, col, np.where(outside, np.uint8(Status.OUT_OF_DOMAIN), np.uint8(0))


def test_footprint_through_pixel_centres():
    with pytest.raises(AssertionError,
                       match=r"first footprint vertex is not the outer corner(.|\n)*"
                       r"centre of pixel \(0, 0\)"):
        check_footprint(affine(CentreFootprint))


def test_model_refusing_pixel_edges():
    with pytest.raises(AssertionError, match=r"backproject fails(.|\n)*row=-0\.5, col=-0\.5"
                       r"(.|\n)*status (OUT_OF_DOMAIN|DIVERGED|MAX_ITERATIONS)"):
        check_footprint(affine(NarrowDomain))


# ============================================================= the whole kit
class DuckTypedAffine:
    """A SensorModel by protocol only: delegates to an AffineCamera, no SensorModelBase, no
    footprint or los."""

    name: ClassVar[str] = "duck-affine"
    schema_version: ClassVar[int] = 1

    def __init__(self, inner: AffineCamera) -> None:
        self._inner = inner

    shape = property(lambda self: self._inner.shape)
    height_range = property(lambda self: self._inner.height_range)
    parameters = property(lambda self: self._inner.parameters)

    def project(self, lon, lat, h):
        return self._inner.project(lon, lat, h)

    def backproject(self, row, col, h):
        return self._inner.backproject(row, col, h)

    def project_with_status(self, lon, lat, h):
        return self._inner.project_with_status(lon, lat, h)

    def backproject_with_status(self, row, col, h):
        return self._inner.backproject_with_status(row, col, h)

    def partials_ground(self, lon, lat, h):
        return self._inner.partials_ground(lon, lat, h)

    def partials_parameters(self, lon, lat, h):
        return self._inner.partials_parameters(lon, lat, h)

    def with_parameters(self, values):
        return type(self)(self._inner.with_parameters(values))

    parameter_sets = ("default",)

    def with_parameter_set(self, name, **options):
        return type(self)(self._inner.with_parameter_set(name, **options))

    def to_dict(self):
        return {**self._inner.to_dict(), "model": self.name}

    @classmethod
    def from_dict(cls, data):
        return cls(AffineCamera.from_dict({**data, "model": AffineCamera.name}))

    def __eq__(self, other):
        return type(other) is type(self) and (
            json.dumps(self.to_dict(), sort_keys=True)
            == json.dumps(other.to_dict(), sort_keys=True)
        )

    def __hash__(self):
        return hash(json.dumps(self.to_dict(), sort_keys=True))

    def __dask_tokenize__(self):
        return (self.name, json.dumps(self.to_dict(), sort_keys=True))


def test_a_protocol_only_model_passes():
    model = DuckTypedAffine(AffineCamera.example())
    assert not isinstance(model, SensorModelBase)
    check_sensor_model(model, n=3)


def test_healthy_models_pass():
    check_sensor_model(AffineCamera.example(), n=3)
    check_sensor_model(ConstantVelocityPushbroom.example(roll=0.01), n=3)


def test_check_sensor_model_reports_every_failed_check():
    with pytest.raises(AssertionError) as info:
        check_sensor_model(pushbroom(LossyToDict), n=3)
    text = str(info.value)
    assert text.startswith("4 of 15 conformance checks failed for LossyToDict 'broken-lossy'"), text
    for name in (
        "check_with_parameters", "check_serialization", "check_pickle", "check_dask_token"
    ):
        assert f"{name} failed" in text, text


def test_check_sensor_model_skip():
    check_sensor_model(pushbroom(LossyToDict), n=3, skip=[
        "check_with_parameters", "check_serialization", "check_pickle", "check_dask_token"])
    with pytest.raises(ValueError, match="unknown checks"):
        check_sensor_model(AffineCamera.example(), skip=["check_everything"])


def test_tolerance_options_are_passed_on():
    # a 1e-4 px inverse error passes a 1e-3 px tolerance
    check_sensor_model(affine(SloppyInverse), n=3, tolerance_px=1e-3,
                       skip=["check_footprint", "check_nan_isolation"])


def test_exceptions_become_readable_failures():
    class Raising(AffineCamera):
        name: ClassVar[str] = "broken-raising"

        def partials_ground(self, lon, lat, h):
            raise TypeError("not implemented for arrays")

    with pytest.raises(AssertionError, match=r"partials_ground\(lon, lat, h\) raised TypeError: "
                       r"not implemented for arrays"):
        check_ground_partials(affine(Raising), n=3)


def test_contract_has_one_test_per_check():
    tests = {name for name in dir(SensorModelContract) if name.startswith("test_")}
    expected = {"test_" + check.__name__.removeprefix("check_") for check in CHECKS}
    assert tests == expected


class TestContractOnProtocolOnlyModel(SensorModelContract):
    check_options: ClassVar[dict] = {"n": 3}

    @pytest.fixture
    def model(self):
        return DuckTypedAffine(AffineCamera.example())


def test_contract_options_reach_the_checks(monkeypatch):
    seen = {}

    def fake(model, *, n=5, seed=0, tolerance_px=1e-6):
        seen.update(n=n, seed=seed, tolerance_px=tolerance_px)

    class Options(SensorModelContract):
        check_options: ClassVar[dict] = {"n": 2, "tolerance_px": 1e-3, "partials_rtol": 1e-2}

    monkeypatch.setattr(checks, "check_round_trip", fake)
    Options().test_round_trip(AffineCamera.example())
    assert seen == {"n": 2, "seed": 0, "tolerance_px": 1e-3}


def test_partials_together_catches_a_model_whose_partials_disagree():
    """A model whose combined partials() scales the parameter partials (a unit slip in one
    of its two code paths) is caught; the synthetic pushbroom's own passes."""

    class Slipped(ConstantVelocityPushbroom):
        def partials(self, lon, lat, h):
            ground, params = super().partials(lon, lat, h)
            return ground, params * (180.0 / math.pi)

    model = ConstantVelocityPushbroom.example()
    checks.check_partials_together(model)
    broken = model.__class__.__new__(Slipped)
    broken.__dict__.update(model.__dict__)
    with pytest.raises(AssertionError, match="partials_parameters"):
        checks.check_partials_together(broken)

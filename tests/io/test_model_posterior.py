"""A model's posterior covariance in its model JSON (issue 28, item 3: the accuracy layer's
source after ``geoblock adjust``)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import geoblock
from geoblock.errors import ModelFormatError, UnsupportedFormatError
from geoblock.io import open_model, write_model
from geoblock.io.models import read_model_json, read_model_posterior, write_model_json
from geoblock.models import ImageCorrection
from geoblock.models.uncertainty import ModelPosterior, NoAccuracyError
from geoblock.plugins import get_registry


def _examples():
    registry = get_registry()
    out = []
    for name in registry.names():
        cls = registry.get(name)
        if hasattr(cls, "example"):
            out.append(pytest.param(cls, id=name))
    return out


def _posterior(model, source="geoblock adjust test.toml"):
    names = model.parameters.names[:3]
    k = len(names)
    a = np.arange(1.0, 1.0 + k * k).reshape(k, k) * 1e-3
    cov = a @ a.T + np.eye(k) * 1e-4
    return ModelPosterior(names, cov, 1.07, 123, source)


@pytest.mark.parametrize("cls", _examples())
def test_every_model_kind_round_trips_with_a_posterior(tmp_path, cls):
    """Each registered model with an example: written with a posterior, it opens as before
    (the key never reaches its from_dict) and the posterior reads back equal."""
    model = cls.example()
    post = _posterior(model)
    path = write_model(model, tmp_path / "m.json", posterior=post)
    assert "posterior" in json.loads(path.read_text())
    assert open_model(path) == model
    back = read_model_posterior(path)
    assert back is not None
    assert back.names == post.names and back.source == post.source
    np.testing.assert_array_equal(back.covariance, post.covariance)
    assert back.sigma0 == 1.07 and back.dof == 123
    assert "posterior" not in read_model_json(path)


@pytest.mark.parametrize("cls", _examples())
def test_without_a_posterior_the_file_is_unchanged(tmp_path, cls):
    model = cls.example()
    path = write_model(model, tmp_path / "m.json")
    text = json.dumps(model.to_dict(), indent=1, sort_keys=True, allow_nan=False) + "\n"
    assert path.read_bytes() == text.encode()
    assert read_model_posterior(path) is None


def test_refusals(tmp_path, data_dir):
    rpc = open_model(data_dir / "gdal-autotest/gcore/data/md_dg.RPB")
    model = ImageCorrection(rpc, 0)
    wrong = ModelPosterior(("a0", "roll_bias"), np.eye(2), None, None, "x")
    with pytest.raises(NoAccuracyError, match="roll_bias"):
        write_model(model, tmp_path / "m.json", posterior=wrong)
    assert not (tmp_path / "m.json").exists()
    with pytest.raises(UnsupportedFormatError, match="JSON only"):
        write_model(model, tmp_path / "m.txt", format="rpc-txt",
                    posterior=_posterior(model))
    # a malformed entry names the file
    path = write_model_json(model, tmp_path / "m.json", posterior=_posterior(model))
    data = json.loads(path.read_text())
    data["posterior"]["covariance"] = [[1.0, 2.0]]
    path.write_text(json.dumps(data))
    with pytest.raises(ModelFormatError, match="m.json"):
        read_model_posterior(path)
    assert open_model(path) == model  # the model itself still opens
    # not model JSON at all: None
    assert read_model_posterior(data_dir / "gdal-autotest/gcore/data/md_dg.RPB") is None


def test_from_block_result_skips_a_collocated_model():
    class Result:
        sigma0, dof = 1.2, 50
        models = {"a": ImageCorrection(geoblock.testing.synthetic.AffineCamera.example(), 0),
                  "b": geoblock.adjust.collocation.CollocationCorrection.example()}

        def parameter_covariance(self, image):
            return ("a0", "b0"), np.diag([0.1, 0.2])

    post = ModelPosterior.from_block_result(Result(), "a", "geoblock adjust blk.toml")
    assert post is not None and post.names == ("a0", "b0") and post.dof == 50
    assert ModelPosterior.from_block_result(Result(), "b") is None


@settings(max_examples=40, deadline=None)
@given(k=st.integers(0, 5), seed=st.integers(0, 2**31), sigma0=st.none() | st.floats(0.1, 10),
       dof=st.none() | st.integers(0, 10**6), source=st.text(max_size=30))
def test_posterior_dict_round_trip(k, seed, sigma0, dof, source):
    a = np.random.default_rng(seed).normal(size=(k, k))
    post = ModelPosterior(tuple(f"p{i}" for i in range(k)), a @ a.T, sigma0, dof, source)
    back = ModelPosterior.from_dict(json.loads(json.dumps(post.to_dict())))
    assert back.names == post.names and back.source == post.source
    assert back.sigma0 == post.sigma0 and back.dof == post.dof
    np.testing.assert_array_equal(back.covariance, post.covariance)

"""open_model / write_model / from_dict through the plugin hooks."""

import json

import numpy as np
import pytest

import geoblock
from geoblock.errors import (
    GeoblockIOError,
    ModelFormatError,
    SerializationError,
    UnknownModelError,
    UnsupportedFormatError,
)
from geoblock.testing.synthetic import AffineCamera, ConstantVelocityPushbroom


def test_json_round_trip(tmp_path, synthetic_model):
    path = geoblock.write_model(synthetic_model, tmp_path / "model.json")
    again = geoblock.open_model(path)
    assert again == synthetic_model
    assert type(again) is type(synthetic_model)


def test_json_round_trip_of_a_correction(tmp_path, pushbroom):
    model = geoblock.ImageCorrection(pushbroom, 1, [1, 2, 3, 4, 5, 6], sigmas=2.0)
    again = geoblock.open_model(geoblock.write_model(model, tmp_path / "m.json"))
    assert again == model
    assert again.model == pushbroom and np.all(again.parameters.sigmas == 2.0)


def test_model_option_selects_or_refuses(tmp_path, affine_camera):
    path = geoblock.write_model(affine_camera, tmp_path / "m.json")
    assert geoblock.open_model(path, model="synthetic-affine") == affine_camera
    with pytest.raises(UnsupportedFormatError, match="as model 'synthetic-pushbroom'"):
        geoblock.open_model(path, model="synthetic-pushbroom")
    with pytest.raises(UnknownModelError, match=r"no sensor model named 'nope'.*image-correction"):
        geoblock.open_model(path, model="nope")


def test_unknown_file_names_file_plugins_and_models(tmp_path):
    path = tmp_path / "scene.xyz"
    path.write_text("hello")
    with pytest.raises(UnsupportedFormatError) as err:
        geoblock.open_model(path)
    message = str(err.value)
    assert "scene.xyz" in message
    assert "geoblock._default_plugin" in message  # a reader consulted
    assert "synthetic-affine" in message  # the registered models


def test_missing_file(tmp_path):
    with pytest.raises(GeoblockIOError, match="does not exist"):
        geoblock.open_model(tmp_path / "nothing.json")
    # a directory is offered to the readers (product directories); none reads this one
    with pytest.raises(UnsupportedFormatError, match="product directory"):
        geoblock.open_model(tmp_path)


def test_json_of_a_newer_schema_is_refused(tmp_path, affine_camera):
    data = affine_camera.to_dict()
    data["schema_version"] = 99
    path = tmp_path / "m.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ModelFormatError, match=r"m\.json.*schema_version 99"):
        geoblock.open_model(path)


def test_from_dict_errors(affine_camera):
    with pytest.raises(SerializationError, match="string field 'model'"):
        geoblock.from_dict({"shape": [1, 1]})
    with pytest.raises(UnknownModelError):
        geoblock.from_dict({"model": "nope", "schema_version": 1})
    data = affine_camera.to_dict()
    del data["origin"]
    with pytest.raises(SerializationError, match="'synthetic-affine'.*origin"):
        geoblock.from_dict(data)


def test_write_errors(tmp_path, affine_camera):
    with pytest.raises(UnsupportedFormatError, match="pass format="):
        geoblock.write_model(affine_camera, tmp_path / "m.txt")
    with pytest.raises(UnsupportedFormatError, match="as 'nitf'"):
        geoblock.write_model(affine_camera, tmp_path / "m.txt", format="nitf")
    with pytest.raises(GeoblockIOError, match="does not exist"):
        geoblock.write_model(affine_camera, tmp_path / "no" / "m.json")


def test_not_json_safe_model_is_refused(tmp_path):
    model = ConstantVelocityPushbroom.example()
    bad = type(
        "Bad", (ConstantVelocityPushbroom,), {"name": "bad", "to_dict": lambda self: {"x": np.nan}}
    )
    with pytest.raises(ModelFormatError, match="not JSON-safe"):
        geoblock.write_model(bad.example(), tmp_path / "m.json")
    assert model  # the good one still writes
    geoblock.write_model(model, tmp_path / "ok.json")
    assert isinstance(geoblock.open_model(tmp_path / "ok.json"), ConstantVelocityPushbroom)
    assert AffineCamera.example() != model


def test_a_model_json_refused_by_its_model_names_the_file(tmp_path):
    """Any model's refusal of its fields (here a collocation with two coincident control
    points) comes out of open_model naming the file."""
    import json

    import geoblock
    from geoblock.adjust.collocation import CollocationCorrection
    from geoblock.errors import ModelFormatError

    data = CollocationCorrection.example().to_dict()
    col = data["collocation"]
    for key in ("row", "col"):
        col[key][1] = col[key][0]
    path = tmp_path / "bad-collocation.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ModelFormatError, match="bad-collocation.json"):
        geoblock.open_model(path)


def test_model_json_is_sniffed_by_geoblock_io(tmp_path, affine_camera):
    """The built-in plugin reads and writes model JSON through geoblock.io.models; anything
    that is not model JSON is left to the other readers (None), not an error."""
    from geoblock.io.models import read_model_json, write_model_json

    path = write_model_json(affine_camera, tmp_path / "m.JSON")
    assert path.read_text().endswith("}\n")
    assert read_model_json(path) == json.loads(path.read_text()) == affine_camera.to_dict()
    (tmp_path / "m.txt").write_text(path.read_text())
    (tmp_path / "list.json").write_text("[1, 2]")
    (tmp_path / "other.json").write_text('{"model": "x"}')  # no schema_version
    (tmp_path / "latin1.json").write_bytes('{"model": "caf\xe9"}'.encode("latin-1"))
    (tmp_path / "broken.json").write_text('{"model": ')
    (tmp_path / "dir.json").mkdir()
    for name in ("m.txt", "list.json", "other.json", "latin1.json", "broken.json", "dir.json"):
        assert read_model_json(tmp_path / name) is None, name

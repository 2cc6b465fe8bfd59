"""Contract checks (placeholder, being written)."""


def check_sensor_model(model, **kwargs):  # pragma: no cover - placeholder
    raise NotImplementedError

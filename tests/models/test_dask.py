"""Models travel to dask workers as values: pickled through to_dict, same results there."""

from __future__ import annotations

import numpy as np
import pytest

import geoblock


@pytest.mark.slow
def test_models_project_identically_on_a_distributed_worker(affine_camera, pushbroom):
    distributed = pytest.importorskip("distributed")
    corrected = geoblock.ImageCorrection(pushbroom, 1, [1.0, 0.5, -0.2, -1.0, 0.1, 0.3])
    rows = np.linspace(0.0, 799.0, 7)
    cols = np.linspace(0.0, 999.0, 7)

    def backproject(model, r, c):
        return np.stack(model.backproject(r, c, 250.0))

    with distributed.LocalCluster(
        n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as client:
        for model in (affine_camera, corrected):
            remote = client.submit(backproject, model, rows, cols).result()
            assert np.array_equal(remote, backproject(model, rows, cols))

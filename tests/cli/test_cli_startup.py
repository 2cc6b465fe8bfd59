"""Start-up: commands import only what they use, and the numba kernels load from their on-disk
cache instead of compiling in every process.

The times themselves are measured in ``benchmarks/bench_ortho_cli.py`` (no timed assertions in
tests); these tests fail when what makes them short breaks: a heavy import at module level of
the CLI, of ``geoblock`` or of a plugin's hook module, or a kernel that recompiles per process.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import numpy as np

import geoblock

#: Libraries ``geoblock --help`` must not import (numba 0.2 s, dask.array 0.6 s, xarray 0.3 s,
#: scipy.stats 0.6 s, distributed 0.3 s...).
HEAVY = ("numba", "dask", "xarray", "scipy", "pyproj", "rasterio", "pandas", "matplotlib",
         "distributed", "cv2")


def _run(code: str, *, synthetic: bool = False) -> str:
    """The last line ``code`` prints, run in a new interpreter as a user's would be: without
    the test run's ``GEOBLOCK_PLUGIN_MODULES`` (geoblock's synthetic test models) unless
    ``synthetic``."""
    env = {k: v for k, v in os.environ.items()
           if synthetic or k != "GEOBLOCK_PLUGIN_MODULES"}
    proc = subprocess.run([sys.executable, "-c", textwrap.dedent(code)], capture_output=True,
                          text=True, check=True, env=env)
    return proc.stdout.strip().splitlines()[-1]


def _modules_after_cli(args: list[str]) -> list[str]:
    return json.loads(_run(f"""
        import json, sys
        from geoblock.cli.main import main
        try:
            main({args!r})
        except SystemExit:
            pass
        print(json.dumps(sorted(m for m in {HEAVY!r} if m in sys.modules)))
    """))


def test_help_imports_no_heavy_library():
    """``geoblock --help`` loads every plugin's commands (rpc, spot, quickbird, the example
    plugin) and none of the numerical libraries."""
    assert _modules_after_cli(["--help"]) == []
    assert _modules_after_cli(["ortho", "--help"]) == []
    assert _modules_after_cli(["mosaic", "--help"]) == []
    assert _modules_after_cli(["match", "--help"]) == []


def test_opening_a_model_loads_no_adjustment_or_dask(tmp_path):
    from geoblock.testing.synthetic import AffineCamera

    path = geoblock.write_model(AffineCamera.example(), tmp_path / "m.json")
    loaded = json.loads(_run(f"""
        import json, sys
        import geoblock
        geoblock.open_model({str(path)!r})
        print(json.dumps(sorted(m for m in ("dask", "xarray", "scipy.stats", "scipy.linalg",
                                            "distributed", "pandas") if m in sys.modules)))
    """, synthetic=True))
    assert loaded == []


def test_lazy_names_resolve_and_shadowing_submodules_stay_functions():
    """``geoblock``, ``geoblock.ortho`` and ``geoblock.adjust`` import their public names on
    first use; the functions named like their submodule (``resect``, ``mosaic``) are still the
    functions after the submodule has been imported."""
    out = _run("""
        import geoblock.adjust.resect, geoblock.ortho.mosaic
        from geoblock.adjust import resect
        from geoblock.ortho import mosaic, orthorectify
        import geoblock
        ok = [callable(resect), callable(mosaic), callable(orthorectify),
              callable(geoblock.open_model), "open_dem" in dir(geoblock)]
        try:
            geoblock.no_such_name
        except AttributeError:
            ok.append(True)
        print(all(ok))
    """)
    assert out == "True"
    import geoblock.ortho

    assert set(geoblock.__all__) <= set(dir(geoblock))
    assert all(hasattr(geoblock.ortho, name) for name in geoblock.ortho.__all__)


def test_numba_kernels_load_from_the_cache_in_a_new_process(tmp_path):
    """A second process running an orthorectification compiles nothing: every kernel it calls
    (``lazy_njit`` ones included) is loaded from numba's on-disk cache (written by the first, in the default place beside
    the sources, which the rest of the test run then reuses too)."""
    from geoblock.testing.synthetic import ConstantVelocityPushbroom

    model = geoblock.write_model(ConstantVelocityPushbroom.example((60, 80)), tmp_path / "m.json")
    image = tmp_path / "img.npy"
    np.save(image, np.arange(60 * 80, dtype=np.uint16).reshape(60, 80))
    code = f"""
        import json, sys
        import numpy as np
        import numba.core.registry
        import geoblock
        from geoblock._jit import LazyKernel
        from geoblock.io import write_ortho
        from geoblock.ortho import ortho_job
        model = geoblock.open_model({str(model)!r})
        job = ortho_job(np.load({str(image)!r}), model, 300.0, chunks=32)
        write_ortho(job, {str(tmp_path / "o.tif")!r}, empty="ignore")
        hits = misses = 0
        uncached = []
        for name, module in list(sys.modules.items()):
            if not name.startswith("geoblock"):
                continue
            for key, value in vars(module).items():
                if isinstance(value, LazyKernel) and value.loaded:  # geoblock._jit.lazy_njit
                    value = value.load()
                if isinstance(value, numba.core.registry.CPUDispatcher) and value.signatures:
                    hits += sum(value.stats.cache_hits.values())
                    misses += sum(value.stats.cache_misses.values())
                    if type(value._cache).__name__ == "NullCache":  # njit without cache=True
                        uncached.append(f"{{name}}.{{key}}")
        print(json.dumps([hits, misses, uncached]))
    """
    _run(code, synthetic=True)  # the first process compiles (or loads) and writes the cache
    hits, misses, uncached = json.loads(_run(code, synthetic=True))
    assert uncached == []
    assert misses == 0 and hits > 5, (hits, misses)

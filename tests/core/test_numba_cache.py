"""Importing the kernels works for a user who can write neither the package's
``__pycache__`` nor a home cache folder."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

# Run in a fresh interpreter: numba's cache locators are patched to fail for every
# folder except those under ALLOWED (the temporary directory, or nothing at all).
SCRIPT = textwrap.dedent("""
    import os, sys
    from numba.core import caching, config
    allowed = sys.argv[1]
    real = caching._CacheLocator.ensure_cache_path

    def ensure(self):
        if not allowed or not self.get_cache_path().startswith(allowed):
            raise PermissionError(13, "Permission denied", self.get_cache_path())
        return real(self)

    caching._CacheLocator.ensure_cache_path = ensure
    import numpy as np
    import stbs
    import stbs.geometry._winding, stbs.meshing._kernels, stbs.weights._dense
    from stbs.skinning import Deformer
    V = np.random.default_rng(0).normal(size=(50, 3))
    sk = stbs.Skeleton(np.array([[0.0, 0, 0], [1, 0, 0]]), np.array([[0, 1]]))
    W = np.ones((50, 1))
    U = Deformer(V, sk, W, method="lbs")(stbs.Pose.rest(sk))
    assert np.allclose(U, V)
    print("cache dir", repr(config.CACHE_DIR))
""")


@pytest.mark.parametrize("allowed", ["tmp", ""], ids=["temp folder writable", "nothing writable"])
def test_kernels_import_without_a_writable_cache_folder(tmp_path, allowed):
    env = dict(os.environ, TMPDIR=str(tmp_path))
    env.pop("NUMBA_CACHE_DIR", None)
    r = subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path) if allowed else ""],
                       capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    if allowed:
        assert f"stbs-numba-{os.getuid()}" in r.stdout
        assert any((tmp_path / f"stbs-numba-{os.getuid()}").rglob("*.nbi"))
    else:
        assert "cache dir ''" in r.stdout

"""A wheel of the project carries the shipped bundles: installed into a fresh virtualenv,
``python -m experiments.register`` run from another folder loads LEAD-PN from the package."""
import glob
import os
import subprocess
import sys
import venv
import zipfile

import numpy as np
import pytest

from sphere_jax import paths
from sphere_jax.data import demo
from sphere_jax.data.readers import io
from sphere_jax.eval import registration

pytestmark = pytest.mark.slow     # minutes: left out of the everyday `-m "not slow"` loop

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_wheel_holds_the_bundles_and_registers_from_elsewhere(tmp_path):
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", ROOT, "--no-deps", "-q", "-w",
                    str(wheels)], check=True, timeout=600)
    wheel = glob.glob(str(wheels / "sphere_jax-*.whl"))[0]
    names = zipfile.ZipFile(wheel).namelist()
    for name in paths.SHIPPED.values():
        assert f"sphere_jax/weights/{name}/bundle/config.json" in names, name
        assert any(n.startswith(f"sphere_jax/weights/{name}/bundle/variables/") for n in names)
    # The dependencies come from this interpreter's site-packages; sphere_jax from the wheel.
    env_dir = tmp_path / "env"
    venv.create(env_dir, system_site_packages=True, with_pip=True)
    python = str(env_dir / "bin" / "python")
    subprocess.run([python, "-m", "pip", "install", "-q", "--no-deps", wheel], check=True,
                   timeout=600)
    (src, dst), t_gt = demo.fragment_pair()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    io.write_ply(elsewhere / "a.ply", src)
    io.write_ply(elsewhere / "b.ply", dst)
    clean = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",
                                                              "SPHERE_JAX_WEIGHTS")}
    where = subprocess.run([python, "-c", "import sphere_jax, sphere_jax.paths as p; "
                            "print(sphere_jax.__file__); print(p.shipped_bundle('lead_pn'))"],
                           cwd=elsewhere, env=clean, capture_output=True, text=True, check=True)
    module, bundle = where.stdout.split()
    assert module.startswith(str(env_dir)) and bundle.startswith(str(env_dir)), where.stdout
    out = subprocess.run([python, "-m", "experiments.register", "a.ply", "b.ply",
                          "--keypoints=1500", "--out=result"], cwd=elsewhere, env=clean,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "lead_pn:" in out.stdout
    t = np.loadtxt(elsewhere / "result" / "transform.txt")
    rre, rte = registration.rre_rte(t, t_gt)
    assert rre < 5.0 and rte < 0.10, out.stdout

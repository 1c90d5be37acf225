"""A wheel of the project is the checkout: installed into a fresh virtualenv that reuses this
environment's dependencies, run from another folder, it holds every file of every shipped
bundle, describes a real fragment exactly as the checkout does with each shipped descriptor,
and registers a pair."""
import glob
import os
import site
import subprocess
import sys
import venv
import zipfile

import numpy as np
import pytest

from sphere_jax.data import demo
from sphere_jax.data.readers import io
from sphere_jax.eval import registration
from sphere_jax.models import shipped

pytestmark = pytest.mark.slow     # minutes: left out of the everyday `-m "not slow"` loop

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# Run by both interpreters: the shipped descriptors of 300 keypoints of a.ply, as describe()
# gives them to a user (LEAD in Compass's frames whitened, LEAD-PN and SOUND whitened).
DESCRIBE = """
import sys, numpy as np, sphere_jax
from sphere_jax.data import patches
from sphere_jax.data.readers import io
pts = patches.voxel_downsample(io.read_points(sys.argv[1]).points, 0.03)
kp = patches.random_keypoints(pts, 300, np.random.default_rng(0))
frames = sphere_jax.orient("compass", pts, kp, radius=0.3)
out = {"compass": frames,
       "lead_compass": sphere_jax.describe("lead", pts, kp, radius=0.3, frames=frames,
                                           whiten="compass"),
       "lead_pn": sphere_jax.describe("lead_pn", pts, kp, radius=0.3),
       "sound": sphere_jax.describe("sound", pts, kp, radius=0.3)}
np.savez(sys.argv[2], **{k: np.asarray(v) for k, v in out.items()})
print(sphere_jax.__file__)
"""


def _wheel(tmp_path):
    wheels = tmp_path / "wheels"
    subprocess.run([sys.executable, "-m", "pip", "wheel", ROOT, "--no-deps", "-q", "-w",
                    str(wheels)], check=True, timeout=600)
    return glob.glob(str(wheels / "sphere_jax-*.whl"))[0]


def _env_reusing_these_dependencies(env_dir, wheel):
    """A virtualenv with sphere_jax from ``wheel`` only, and this interpreter's
    site-packages (a virtualenv's own, not its base's) behind it through a ``.pth`` file: no
    network, and no path to the checkout (an editable install's hook is not run from there)."""
    venv.create(env_dir, with_pip=True)
    python = str(env_dir / "bin" / "python")
    own = subprocess.run([python, "-c", "import site; print(site.getsitepackages()[0])"],
                         capture_output=True, text=True, check=True).stdout.strip()
    ours = [p for p in site.getsitepackages() + [site.getusersitepackages()]
            if os.path.isdir(p)]
    with open(os.path.join(own, "reused_dependencies.pth"), "w") as f:
        f.write("\n".join(ours) + "\n")
    subprocess.run([python, "-m", "pip", "install", "-q", "--no-deps", "--no-index", wheel],
                   check=True, timeout=600)
    return python


def test_wheel_equals_the_checkout(tmp_path):
    wheel = _wheel(tmp_path)
    names = set(zipfile.ZipFile(wheel).namelist())
    weights = os.path.join(ROOT, "sphere_jax", "weights")
    tracked = subprocess.run(["git", "ls-files", "sphere_jax/weights"], cwd=ROOT,
                             capture_output=True, text=True).stdout.split()
    bundle_files = tracked or [os.path.relpath(os.path.join(d, f), ROOT)
                               for d, _, fs in os.walk(weights) for f in fs]
    missing = [f for f in bundle_files if f.replace(os.sep, "/") not in names]
    assert not missing, f"the wheel lacks {len(missing)} bundle files, e.g. {missing[:3]}"
    for name in (row.folder for row in shipped.SHIPPED.values()):
        assert f"sphere_jax/weights/{name}/bundle/config.json" in names, name

    python = _env_reusing_these_dependencies(tmp_path / "env", wheel)
    (src, dst), t_gt = demo.fragment_pair()
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    io.write_ply(elsewhere / "a.ply", src)
    io.write_ply(elsewhere / "b.ply", dst)
    clean = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH",
                                                              "SPHERE_JAX_WEIGHTS")}
    (tmp_path / "describe.py").write_text(DESCRIBE)
    runs = {}
    for who, exe, cwd in (("wheel", python, elsewhere), ("checkout", sys.executable, ROOT)):
        out = subprocess.run([exe, str(tmp_path / "describe.py"), str(elsewhere / "a.ply"),
                              str(tmp_path / f"{who}.npz")], cwd=cwd, env=clean,
                             capture_output=True, text=True, timeout=900)
        assert out.returncode == 0, out.stderr[-2000:]
        runs[who] = out.stdout.strip()
    assert runs["wheel"].startswith(str(tmp_path / "env")), runs
    assert runs["checkout"].startswith(ROOT), runs
    with np.load(tmp_path / "wheel.npz") as w, np.load(tmp_path / "checkout.npz") as c:
        assert sorted(w.files) == ["compass", "lead_compass", "lead_pn", "sound"]
        for k in w.files:
            np.testing.assert_allclose(w[k], c[k], atol=1e-5, err_msg=k)

    out = subprocess.run([python, "-m", "experiments.register", "a.ply", "b.ply",
                          "--keypoints=1500", "--out=result"], cwd=elsewhere, env=clean,
                         capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    assert "lead_pn:" in out.stdout
    t = np.loadtxt(elsewhere / "result" / "transform.txt")
    rre, rte = registration.rre_rte(t, t_gt)
    assert rre < 5.0 and rte < 0.10, out.stdout

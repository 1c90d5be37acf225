"""LEAD-PN: its code is rotation invariant through the FLARE frame it describes the patch in."""
import jax
import numpy as np

from sphere_jax import models
from sphere_jax.models import lead_pn
from tests import reference
from tests.models import _helpers


def test_codes_do_not_change_when_the_patch_rotates(capsys):
    model = models.LeadPN(features=(16, 32, 64), decoder_side=3, decoder_hidden=(8, 8, 8))
    p = _helpers.surfaces(8, 512)
    variables = reference.init(model, p)
    describe = jax.jit(lambda x: lead_pn.describe(model, variables, x))
    base = np.asarray(describe(p))
    errs = []
    for seed in range(3):
        rot = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))[0]
        rot *= np.sign(np.linalg.det(rot))
        got = np.asarray(describe((p @ rot.T).astype(np.float32)))
        errs.append(np.linalg.norm(got - base, axis=1) / np.linalg.norm(base, axis=1))
    errs = np.concatenate(errs)
    other = np.linalg.norm(base - np.roll(base, 1, 0), axis=1) / np.linalg.norm(base, axis=1)
    with capsys.disabled():
        print(f"\n  LEAD-PN code change under rotation: median {np.median(errs):.2e}, max "
              f"{errs.max():.2e} (other patches: {np.median(other):.2f})")
    # FLARE rotates exactly with the points, so only float round-off remains.
    assert np.median(errs) < 1e-4 and np.median(other) > 1e-2

"""``sphere_jax.register``: two real fragments registered within 5° and 10 cm of the ground
truth by the shipped LEAD-PN, the same pair at 10× the scale by the automatic scale, and the
command line's outputs."""
import dataclasses
import os
import re

import numpy as np
import pytest

import sphere_jax
from experiments import register as register_cli
from sphere_jax import align, paths
from sphere_jax.data import demo
from sphere_jax.data.readers import io
from sphere_jax.eval import registration
from sphere_jax.features import registry
from sphere_jax.bundles import whitening
from sphere_jax.registration import pipeline
from sphere_jax.registration import scale as scales
from sphere_jax.models import shipped


@pytest.fixture(scope="module")
def pair():
    return demo.fragment_pair()      # redkitchen 5 -> 0 (or a synthetic room pair)


@pytest.mark.slow
@pytest.mark.parametrize("scale", [1.0, 10.0])
def test_register_real_fragments_at_any_scale(pair, scale):
    (src, dst), t_gt = pair
    t_gt = t_gt.copy()
    t_gt[:3, 3] *= scale
    result = sphere_jax.register(src * scale, dst * scale, n_keypoints=2500)
    rre, rte = registration.rre_rte(result.transform, t_gt)
    assert rre < 5.0 and rte < 0.10 * scale, (rre, rte, result.summary())
    # Auto scale follows the unit exactly; on 3DMatch fragments it is their 2 cm grid.
    assert result.voxel == pytest.approx(scale * scales.auto_scale(src, dst)[0], rel=1e-4)
    if paths.real_data_root():
        assert result.voxel == pytest.approx(0.02 * scale, rel=0.15)
    assert result.radius == pytest.approx(15 * result.voxel)
    assert result.inliers >= 30 and result.fitness > 0.3


@pytest.mark.slow
def test_register_with_the_pair_vote(pair):
    """LEAD matched in Compass's frames, then again in the frame the matches voted."""
    (src, dst), t_gt = pair
    result = sphere_jax.register(src, dst, method="lead_vote", n_keypoints=1000)
    rre, rte = registration.rre_rte(result.transform, t_gt)
    assert rre < 5.0 and rte < 0.10, (rre, rte, result.summary())
    assert result.inliers >= 30 and result.method == "lead_vote"


def test_auto_scale_follows_extent_and_spacing():
    rng = np.random.default_rng(0)
    wall = np.c_[rng.uniform(0, 2.1, 200_000), rng.uniform(0, 2.1, 200_000), np.zeros(200_000)]
    voxel, radius = scales.auto_scale(wall, wall)
    assert voxel == pytest.approx(0.02, rel=0.05) and radius == pytest.approx(0.3, rel=0.05)
    sparse = wall[:2000]                     # spacing ≈ 2.4 cm > 2 cm: the scan's own spacing
    voxel, _ = scales.auto_scale(sparse, sparse)
    assert voxel == pytest.approx(scales.point_spacing(sparse)) and voxel > 0.02
    with pytest.raises(sphere_jax.SphereJaxError, match="method must be one of"):
        sphere_jax.register(wall, wall, method="orb")
    with pytest.raises(sphere_jax.SphereJaxError, match="voxel must be a positive"):
        sphere_jax.register(wall, wall, voxel=-1)
    with pytest.raises(sphere_jax.SphereJaxError, match="n_keypoints must be a positive"):
        sphere_jax.register(wall, wall, n_keypoints=0)       # not the default in disguise
    with pytest.raises(sphere_jax.SphereJaxError, match="seed must be a non-negative integer"):
        sphere_jax.register(wall, wall, seed="a")
    with pytest.raises(sphere_jax.SphereJaxError, match="bundle must be of a kind that method "
                                                        "'lead' uses .lead.; got a compass"):
        sphere_jax.register(wall, wall, method="lead@flare", bundle="compass")  # never unused
    with pytest.raises(sphere_jax.SphereJaxError, match=r"min_fitness must be a number in "
                                                        r"\[0, 1\]; got 2"):
        sphere_jax.register(wall, wall, min_fitness=2)       # no ICP fitness reaches it


def test_several_bundles_replace_the_shipped_ones_of_their_kinds():
    """``bundle="A,B"`` (or a list): each replaces the shipped bundle of its kind; two of one
    kind, or one the method does not use, are refused before any work."""
    lead_compass = registry.resolve("lead@compass")
    defaults = align.method_bundles(lead_compass)
    for given in ("compass,lead", ["lead", "compass"], " compass , lead "):
        assert align.method_bundles(lead_compass, given) == defaults
    with pytest.raises(sphere_jax.SphereJaxError, match="bundle must be one bundle per kind; "
                                                        "got 2 lead bundles"):
        align.method_bundles(lead_compass, "lead,lead")
    with pytest.raises(sphere_jax.SphereJaxError, match="bundle must be of a kind that method "
                                                        "'lead_compass' uses .lead, compass.; "
                                                        "got a lead_pn"):
        align.method_bundles(lead_compass, "compass,lead_pn")


def test_checking_the_given_bundles_reads_no_weights(monkeypatch):
    """The early check of ``bundle=`` needs only each bundle's kind: its weights are read
    once, later, where they are used."""
    from sphere_jax.bundles import store

    def refuse(path):
        raise AssertionError(f"weights of {path} read by the check")
    monkeypatch.setattr(store, "read_variables", refuse)
    bundles = align.method_bundles(registry.resolve("lead@compass"), "compass,lead")
    assert set(bundles) >= {"compass", "lead"}


def test_a_share_of_the_keypoints_suffices_when_it_registers_with_confidence(
        pair, monkeypatch, tmp_path, capsys):
    """Progressive description: a pair that registers with confidence from a quarter of its
    keypoints stops there; with a confidence the quarter misses it stops at a later share that
    reaches it; with one no consensus reaches it describes the rest and registers with all, as
    a single pass over all of them does."""
    (src, dst), t_gt = pair
    kw = dict(method="fpfh", n_keypoints=4000)
    monkeypatch.setattr(pipeline, "CONFIDENT_INLIERS", 10)
    quarter = sphere_jax.register(src, dst, **kw)
    assert quarter.ok and quarter.keypoints == ((1000, 4000), (1000, 4000)), quarter.summary()
    assert "keypoints described 1000 of 4000, 1000 of 4000" in quarter.summary()
    monkeypatch.setattr(pipeline, "CONFIDENT_INLIERS", quarter.inliers + 1)
    later = sphere_jax.register(src, dst, **kw)
    assert later.keypoints[0] in ((2000, 4000), (4000, 4000))
    assert later.confident or later.keypoints[0] == (4000, 4000)
    monkeypatch.setattr(pipeline, "CONFIDENT_INLIERS", 10 ** 9)
    rest = sphere_jax.register(src, dst, **kw)
    whole = sphere_jax.register(src, dst, progressive=False, **kw)
    assert rest.keypoints == whole.keypoints == ((4000, 4000), (4000, 4000))
    np.testing.assert_allclose(rest.transform, whole.transform, atol=1e-6)
    assert (rest.inliers, rest.matches) == (whole.inliers, whole.matches)
    for result in (quarter, later, rest):
        assert registration.rre_rte(result.transform, t_gt)[0] < 10.0
    # The time of a stage run several times adds up: one entry per stage.
    assert set(rest.seconds) == set(whole.seconds)
    np.save(tmp_path / "src.npy", src)
    np.save(tmp_path / "dst.npy", dst)
    monkeypatch.setattr(pipeline, "CONFIDENT_INLIERS", 10)
    register_cli.main([str(tmp_path / "src.npy"), str(tmp_path / "dst.npy"), "--method=fpfh",
                       "--keypoints=4000", "--no-progressive"])
    assert "keypoints described 4000 of 4000, 4000 of 4000" in capsys.readouterr().out


def test_command_line_writes_matrix_cloud_and_picture(pair, tmp_path, capsys):
    (src, dst), t_gt = pair
    io.write_ply(tmp_path / "src.ply", src)
    np.save(tmp_path / "dst.npy", np.concatenate([dst, np.full((7, 3), np.nan)]))
    out = tmp_path / "out"
    register_cli.main([str(tmp_path / "src.ply"), str(tmp_path / "dst.npy"), "--method=fpfh",
                       "--keypoints=2500", f"--out={out}"])
    printed, said = capsys.readouterr()
    assert f"dst.npy: 7 of {len(dst) + 7} points have non-finite coordinates" in said
    assert "p_target = T · p_source" in printed
    assert f"voxel {scales.auto_scale(src, dst)[0]:.4g}" in printed
    t = np.loadtxt(out / "transform.txt")
    assert registration.rre_rte(t, t_gt)[0] < 10.0
    moved = io.read_ply(out / "source_registered.ply").points
    np.testing.assert_allclose(moved, src @ t[:3, :3].T + t[:3, 3], atol=1e-4)
    assert os.path.getsize(out / "before_after.png") > 10_000


def test_a_registration_that_fails_says_so(pair, tmp_path, capsys):
    """Three points, and two clouds that share nothing: each a failed result with its reason
    (not an identity matrix reported as the transform); the command line prints FAILED and
    exits 3; an --out that cannot be a folder is refused before any work."""
    tiny = sphere_jax.register(np.eye(3), np.eye(3) + 1.0, method="fpfh")
    assert not tiny.ok and tiny.reason.startswith("too few points: source has 3")
    # One finite point cannot give a scale: none is reported (it was 'voxel inf').
    one = sphere_jax.register(np.zeros((1, 3)), np.eye(3), method="fpfh")
    assert np.isnan(one.voxel) and "no voxel or radius chosen" in one.summary()
    (src, dst), _ = pair
    far = np.random.default_rng(0).normal(size=(5000, 3)) * 0.5      # noise, no shared surface
    lost = sphere_jax.register(src, far, method="fpfh", voxel=0.02, radius=0.3, n_keypoints=500)
    assert not lost.ok and ("consensus" in lost.reason or "fitness" in lost.reason), lost.reason
    assert lost.summary().startswith("FAILED: ")
    line = np.c_[np.linspace(0, 1, 2000), np.zeros((2000, 2))]    # one descriptor everywhere
    flat = sphere_jax.register(line, line, method="fpfh")
    assert not flat.ok and flat.reason.endswith("mutual matches (RANSAC needs 3)"), flat.reason
    assert flat.matches < 3
    with pytest.raises(sphere_jax.SphereJaxError, match="icp must be True or False; got str"):
        sphere_jax.register(src, dst, method="fpfh", icp="no")
    np.save(tmp_path / "a.npy", np.eye(3))
    with pytest.raises(SystemExit) as out:
        register_cli.main([str(tmp_path / "a.npy"), str(tmp_path / "a.npy"), "--method=fpfh"])
    assert out.value.code == register_cli.FAILED
    assert capsys.readouterr().out.startswith("FAILED: too few points")
    (tmp_path / "taken").write_text("x")
    with pytest.raises(SystemExit) as out:
        register_cli.main([str(tmp_path / "a.npy"), str(tmp_path / "a.npy"),
                           f"--out={tmp_path / 'taken'}"])
    assert out.value.code == 2 and "--out" in capsys.readouterr().err


def test_few_inliers_are_reported_unconfirmed(pair):
    """Registered with fewer than CONFIDENT_INLIERS, or fewer than RIVAL_MARGIN times the best
    other transform's: still a result, but its summary warns."""
    (src, dst), t_gt = pair
    result = sphere_jax.register(src, dst, method="fpfh", voxel=0.02, radius=0.3)
    assert result.ok, result.summary()
    assert result.rival >= 0
    n = pipeline.CONFIDENT_INLIERS
    enough = dataclasses.replace(result, inliers=n, rival=int(n // pipeline.RIVAL_MARGIN))
    assert enough.confident and enough.summary().startswith("registered\n"), enough.summary()
    few = dataclasses.replace(result, inliers=n - 1, rival=0)
    assert few.ok and not few.confident
    assert few.summary().startswith(f"registered, unconfirmed: {n - 1} "
                                    "RANSAC inliers"), few.summary()
    rivalled = dataclasses.replace(result, inliers=2 * n,
                                   rival=int(2 * n / pipeline.RIVAL_MARGIN) + 1)
    assert rivalled.ok and not rivalled.confident
    assert rivalled.summary().startswith(f"registered, unconfirmed: {2 * n} RANSAC inliers "
                                         f"against {rivalled.rival} for another transform"), \
        rivalled.summary()


@pytest.mark.slow
def test_register_adapts_first_when_asked(pair, tmp_path, capsys):
    """``--adapt``: Compass and LEAD adapted to the two scans side by side (a few seconds
    here) for LEAD (Compass), each kept in OUT/adapted with a card, the adapted LEAD keeping
    the shipped whitening, and the pair still registered within 5° and 10 cm."""
    (src, dst), t_gt = pair
    files = []
    for name, pts in (("src", src), ("dst", dst)):
        files.append(str(tmp_path / f"{name}.npy"))
        np.save(files[-1], pts)
    out = tmp_path / "ab"
    register_cli.main([*files, "--adapt=0.1", f"--out={out}", "--keypoints=2000",
                       "--method=lead@compass"])
    printed = capsys.readouterr().out
    assert "adaptation" in printed and "registered" in printed
    assert re.search(r"\nkept the (adapted bundles' result|result of the bundles as given) "
                     r"\(\d+ RANSAC inliers", printed), printed
    # What each adaptation did, from the adapted bundles' own logs.
    for kind in ("lead", "compass"):
        assert re.search(rf"{kind}: \d+ steps, validation loss [\d.]+ (at the start|->)",
                         printed), printed
        assert (out / "adapted" / kind / "bundle" / "MODEL_CARD.md").is_file()
    statement = whitening.read_statement(str(out / "adapted" / "lead" / "bundle"))
    assert statement["compass"]["kept_from"].endswith("lead_mid/bundle")
    t = np.loadtxt(out / "transform.txt")
    rre, rte = registration.rre_rte(t, t_gt)
    assert rre < 5 and rte < 0.10


@pytest.mark.parametrize("adapted_inliers, kept_adapted", [(None, False), (14, False),
                                                           (15, True), (60, True)])
def test_register_with_adapt_keeps_the_better_of_the_two_results(monkeypatch, adapted_inliers,
                                                                 kept_adapted):
    """Adapting on two scans can lose a pair (a LiDAR rescan pair: 15 inliers before, FAILED
    after), so ``adapt`` registers with the bundles as given and the adapted ones and keeps a
    success over a failure, then the one with more RANSAC inliers (a tie: the adapted)."""
    registered = []

    def fake_match(src, dst, method, bundles, settings, watch):
        adapted = bundles["lead"] == "adapted lead"
        inliers = adapted_inliers if adapted else 15
        result = pipeline.Registration(np.diag([1.0, 1, 1, 1]) * (2 if adapted else 1),
                                       inliers or 8, 500, 0.4, 0.02, 0.02, 0.3, method,
                                       watch.seconds,
                                       "" if inliers else "RANSAC found no consensus")
        registered.append(adapted)
        return result

    monkeypatch.setattr(align, "_match", fake_match)
    monkeypatch.setattr(align, "adapted_bundles", lambda method, bundles, *a, **k: (
        dict(bundles, lead="adapted lead", compass="adapted compass"), "lead: 3 steps"))
    points = np.random.default_rng(0).uniform(0, 1, (2000, 3))
    result = align.register(points, points, method="lead@compass", adapt=1, voxel=0.05,
                            radius=0.5)
    assert registered == [False, True]                        # the given bundles first
    assert (result.transform[0, 0] == 2) == kept_adapted
    assert result.adaptation == "lead: 3 steps"
    given = "15 RANSAC inliers"
    adapted = (f"{adapted_inliers} RANSAC inliers" if adapted_inliers
               else "FAILED, 8 RANSAC inliers")
    assert result.kept == (f"the adapted bundles' result ({adapted}; with the bundles as "
                           f"given: {given})" if kept_adapted else
                           f"the result of the bundles as given ({given}; adapted: {adapted})")
    assert result.summary().endswith("\nkept " + result.kept)
    assert "registration with the bundles as given" in result.seconds


def test_adapt_takes_every_network_of_a_learned_method():
    """``adapt`` fine-tunes the networks a method uses — both of LEAD (Compass) — and refuses
    a hand-crafted method before any work."""
    assert align.adapted_kinds(registry.resolve("lead@compass")) == ("lead", "compass")
    assert align.adapted_kinds(registry.resolve("lead_pn")) == ("lead_pn",)
    assert align.adapted_kinds(registry.resolve("sound")) == ("sound",)
    p = np.random.default_rng(0).uniform(0, 1, (500, 3))
    for method in ("fpfh", "shot+vote"):
        with pytest.raises(sphere_jax.SphereJaxError, match="adapt must be used with a learned "
                                                            "method .lead@flare, lead@compass"):
            align.register(p, p, method=method, adapt=1)


@pytest.mark.slow
def test_an_adapted_sound_keeps_its_bundles_whitening(pair, tmp_path):
    """SOUND is a descriptor: adapted to the two scans, it keeps the shipped bundle's
    whitening (two scans are too few to fit one), and its card says where it came from."""
    from sphere_jax.bundles import inference
    from sphere_jax.bundles import whitening
    (src, dst), _ = pair
    out, note = align.adapted_bundles("sound", {"sound": shipped.bundle_path("sound")},
                                      src, dst, 0.03, 0.45, 0.05, str(tmp_path))
    statement = whitening.read_statement(out["sound"])["default"]
    assert statement["kept_from"].endswith("sound_mid/bundle") and "sound" in note
    kept = inference.load_bundle(out["sound"]).whitenings["default"]
    given = inference.load_bundle("sound").whitenings["default"]
    assert np.array_equal(kept.axes, given.axes) and np.array_equal(kept.mean, given.mean)
    card = open(os.path.join(out["sound"], "MODEL_CARD.md")).read()
    assert "kept from `sphere_jax/weights/sound_mid/bundle`, fitted for its weights" in card

"""The result tables say the settings of the run that made them."""
from sphere_jax.eval import report


def test_titles_carry_the_runs_thresholds():
    reg = dict((k, t) for k, t, _ in report.titled(report.REGISTRATION_TABLES, tau1=0.12,
                                                    tau2=0.08, rre=10.0, rte=0.2))
    assert reg["fmr"] == "Feature-match recall (τ1 = 0.12 m, τ2 = 0.08)"
    assert reg["rr"] == "Registration recall (RANSAC; RRE < 10°, RTE < 0.2 m)"
    lrf = dict((k, t) for k, t, _ in report.titled(report.LRF_TABLES, rho=0.9))
    assert lrf["rep"] == "LRF repeatability (ρ = 0.90)"


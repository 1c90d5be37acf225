"""register's status against the truth: rows re-judged at other thresholds, the table, and the
fit that keeps every wrong result from being called registered."""
from sphere_jax.eval import registered


def _row(method, right, inliers, rival, status="registered"):
    return {"method": method, "right": str(int(right)), "inliers": str(inliers),
            "rival": str(rival), "status": status}


ROWS = [_row("a", True, 120, 10), _row("a", True, 45, 5), _row("a", True, 60, 35),
        _row("a", False, 70, 50), _row("a", False, 41, 30), _row("a", False, 8, -1, "failed"),
        _row("b", True, 30, 3, "unconfirmed")]


def test_status_at_other_thresholds():
    assert registered.status_at(ROWS[0], 40, 2.0) == "registered"
    assert registered.status_at(ROWS[2], 40, 2.0) == "unconfirmed"        # 60 < 2 × 35
    assert registered.status_at(ROWS[4], 50, 1.0) == "unconfirmed"        # 41 < 50
    assert registered.status_at(ROWS[5], 0, 0.0) == "failed"


def test_the_fit_calls_no_wrong_result_registered_and_keeps_the_most_right_ones():
    n, m, kept = registered.fit(ROWS)
    judged = [registered.status_at(r, n, m) for r in ROWS]
    assert all(s != "registered" for s, r in zip(judged, ROWS) if r["right"] == "0")
    # 70 vs 50 and 41 vs 30 are wrong: a margin above 1.4 (or 71+ inliers) excludes them; the
    # right 60 vs 35 (1.7x) stays with a margin of at most 1.71: 1.5 keeps every right one,
    # b's unconfirmed 30 vs 3 included.
    assert (n, m) == (10, 1.5) and kept == 1.0


def test_the_table_counts_right_and_wrong_by_status():
    lines = registered.table(ROWS).splitlines()
    assert lines[0].startswith("| method | pairs | right registered")
    assert lines[2] == "| a | 6 | 3 | 0 | 0 | 2 | 0 | 1 |"
    assert lines[3] == "| b | 1 | 0 | 1 | 0 | 0 | 0 | 0 |"
    assert registered.table(ROWS, 40, 2.0).splitlines()[2] == "| a | 6 | 2 | 1 | 0 | 0 | 2 | 1 |"

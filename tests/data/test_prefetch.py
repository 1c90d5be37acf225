import threading
import time

import pytest

from sphere_jax.data.prefetch import Prefetch


def test_order_and_wait_accounting():
    def make(step):
        time.sleep(0.02)
        return step * 10
    with Prefetch(make, range(3, 8), depth=2) as batches:
        got = list(batches)
        assert got == [(s, s * 10) for s in range(3, 8)]
        # The consumer did nothing else, so it waited for (almost) every batch.
        assert 0.06 < batches.wait_s < 1.0


def test_batches_are_made_ahead_while_the_consumer_works():
    made = []
    with Prefetch(lambda s: made.append(s) or s, range(10), depth=3) as batches:
        it = iter(batches)
        next(it)
        time.sleep(0.2)
        assert len(made) == 5              # one taken, three queued, one waiting to be put
        t0 = time.perf_counter()
        next(it)
        assert time.perf_counter() - t0 < 0.05


def test_an_error_is_raised_at_its_step_and_close_stops_the_thread():
    def make(step):
        if step == 2:
            raise ValueError("bad scan at step 2")
        return step
    seen = []
    with pytest.raises(ValueError, match="step 2"):
        with Prefetch(make, range(5)) as batches:
            for step, _ in batches:
                seen.append(step)
    assert seen == [0, 1]
    p = Prefetch(lambda s: s, range(1000), depth=1)
    p.close()
    assert not any(t.name == "sphere_jax-prefetch" and t.is_alive()
                   for t in threading.enumerate() if t is p._thread)
    with pytest.raises(ValueError, match="depth"):
        Prefetch(lambda s: s, range(2), depth=0)

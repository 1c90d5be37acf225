"""The peer watch of a multi-process run, on an in-memory key-value store: a silent peer or a
lost coordinator ends the process with one line naming it; a peer that finished does not."""
import threading
import time

import pytest

from sphere_jax import parallel


class Store:
    """The coordination service's key-value calls, as JAX's client makes them."""

    def __init__(self):
        self.values, self.down = {}, False

    def key_value_set(self, key, value, allow_overwrite=False):
        if self.down:
            raise RuntimeError("UNAVAILABLE: failed to connect to all addresses")
        self.values[key] = value

    def key_value_try_get(self, key):
        if self.down:
            raise RuntimeError("UNAVAILABLE: failed to connect to all addresses")
        if key not in self.values:
            raise RuntimeError(f"NOT_FOUND: Config key {key} not found.")
        return self.values[key]


def _watch(store, me, timeout_s=1.0):
    exits = []
    done = threading.Event()

    def exit_fn(code):
        exits.append(code)
        done.set()
    watch = parallel.PeerWatch(timeout_s, client=store, me=me, processes=2, exit_fn=exit_fn)
    watch.start()
    return watch, exits, done


def test_a_silent_peer_ends_the_run_with_its_name(capfd):
    store = Store()
    start = time.monotonic()
    watch, exits, done = _watch(store, 0)               # process 1 never beats
    assert done.wait(10)
    took = time.monotonic() - start
    assert exits == [parallel.PEER_LOST_EXIT] and 1.0 < took < 3.0
    last = capfd.readouterr().err.strip().splitlines()[-1]
    assert "process 1 of 2 stopped answering" in last and "same command again" in last
    watch.finish()


def test_beating_and_finished_peers_are_not_lost():
    store = Store()
    w0, exits0, _ = _watch(store, 0)
    w1, exits1, _ = _watch(store, 1)
    time.sleep(2.5)                                     # both beat: nobody is lost
    assert exits0 == exits1 == []
    w1.finish()                                         # 1 ends normally, 0 goes on alone
    time.sleep(2.5)
    assert exits0 == [] and store.values["sphere_jax/peer_watch/done/1"] == "1"
    w0.finish()


def test_a_lost_coordinator_is_named(capfd):
    store = Store()
    store.values["sphere_jax/peer_watch/alive/0"] = "1"
    watch, exits, done = _watch(store, 1)
    store.down = True
    assert done.wait(5) and exits == [parallel.PEER_LOST_EXIT]
    assert "the coordinator (process 0 of 2) no longer answers" in capfd.readouterr().err
    watch.finish()


def test_the_timeout_must_be_positive():
    with pytest.raises(ValueError, match="peer_timeout_s"):
        parallel.initialize("localhost:1", 2, 0, peer_timeout_s=0)

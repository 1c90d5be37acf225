"""The persistent compilation cache: a second process loads what the first compiled, the
folder is per host, ``off`` turns it off and a cache the user chose is kept."""
import json
import os
import subprocess
import sys

from sphere_jax import compile_cache, paths

# A fresh process (this one's JAX already has the tests' cache): enable, compile one program,
# report the folder in use and how many programs came from the disk.
_PROGRAM = """
import json
import jax, jax.numpy as jnp
from sphere_jax import compile_cache
folder = compile_cache.enable()
jax.config.update("jax_persistent_cache_min_compile_time_secs", 0)   # the small program too
events = []
jax.monitoring.register_event_listener(lambda name, **kw: events.append(name))
f = jax.jit(lambda x: jnp.tanh(x @ x.T).sum(0))
f(jnp.ones((64, 64))).block_until_ready()
print(json.dumps({"folder": folder, "hits": sum(e.endswith("/cache_hits") for e in events),
                  "compiled": sum(e.endswith("/compile_requests_use_cache") for e in events)}))
"""


def _run(**env):
    environ = {k: v for k, v in os.environ.items() if k != "JAX_COMPILATION_CACHE_DIR"}
    out = subprocess.run([sys.executable, "-c", _PROGRAM], capture_output=True, text=True,
                         env={**environ, **env}, check=True)
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_second_process_loads_what_the_first_compiled(tmp_path):
    cache = str(tmp_path / "xla")
    first, second = _run(SPHERE_JAX_COMPILE_CACHE=cache), _run(SPHERE_JAX_COMPILE_CACHE=cache)
    assert first["folder"] == cache and first["hits"] == 0 and first["compiled"] >= 1
    assert len(os.listdir(cache)) >= first["compiled"]
    assert second == {**first, "hits": first["compiled"]}          # every program from disk


def test_off_compiles_every_time_and_a_chosen_cache_is_kept(tmp_path):
    off = _run(SPHERE_JAX_COMPILE_CACHE="off")
    assert off["folder"] is None and off["hits"] == 0
    chosen = str(tmp_path / "chosen")
    assert _run(JAX_COMPILATION_CACHE_DIR=chosen, SPHERE_JAX_COMPILE_CACHE=str(tmp_path / "x"))[
        "folder"] == chosen


def test_the_default_folder_names_this_host(monkeypatch):
    monkeypatch.delenv("SPHERE_JAX_COMPILE_CACHE", raising=False)
    folder = paths.compile_cache_dir()
    assert folder.startswith(os.path.join(os.path.expanduser("~"), ".cache", "sphere_jax"))
    assert len(os.path.basename(folder)) == 12 and folder == paths.compile_cache_dir()
    assert compile_cache.MAX_BYTES > 0

"""ml_collections configs, one file per experiment: training configs take
``get_config('paper' | 'mid' | 'small' | 'tiny')``, evaluation configs ``get_config('' | 'quick' |
'tiny')``; eval_lrf adds 'stanford', eval_classification takes the training sizes.
"""
from __future__ import annotations

import os
import re

CONFIG_DIR = os.path.dirname(os.path.abspath(__file__))


def config_names():
    """The experiment names ``--config`` takes (one file each in this folder)."""
    return sorted(f[:-3] for f in os.listdir(CONFIG_DIR) if f.endswith(".py")
                  and not f.startswith("_") and f not in ("common.py", "eval_common.py"))


def resolve_config_arg(argv):
    """Rewrite ``--config=NAME[:ARG]`` to ``--config=<repo>/configs/NAME.py[:ARG]`` so the
    mains accept experiment names as well as paths; an unknown name is a ConfigError listing
    the known ones."""
    from sphere_jax.checks import ConfigError
    out, argv = [], list(argv)
    for k in range(len(argv) - 1, 0, -1):          # '--config NAME', as absl also reads it
        if argv[k - 1] == "--config" and not argv[k].startswith("-"):
            argv[k - 1:k + 1] = [f"--config={argv[k]}"]
    for a in argv:
        m = re.fullmatch(r"--config=([A-Za-z_][A-Za-z0-9_]*)(:[A-Za-z0-9_]+)?", a)
        if m:
            path = os.path.join(CONFIG_DIR, m.group(1) + ".py")
            if not os.path.isfile(path):
                raise ConfigError("--config", "one of " + ", ".join(config_names())
                                  + " (optionally NAME:SIZE) or a config file", m.group(1))
            a = f"--config={path}{m.group(2) or ''}"
        elif a.startswith("--config="):
            file = a.split("=", 1)[1].partition(":")[0]
            if not os.path.isfile(file):
                raise ConfigError("--config", "one of " + ", ".join(config_names())
                                  + " (optionally NAME:SIZE) or a config file", file)
        out.append(a)
    return out

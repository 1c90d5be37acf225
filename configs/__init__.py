"""ml_collections configs, one file per experiment: training configs take
``get_config('paper' | 'cpu' | 'tiny')``, evaluation configs ``get_config('' | 'quick' | 'tiny')``.
"""
from __future__ import annotations

import os
import re

CONFIG_DIR = os.path.dirname(os.path.abspath(__file__))


def resolve_config_arg(argv):
    """Rewrite ``--config=NAME[:ARG]`` to ``--config=<repo>/configs/NAME.py[:ARG]`` so the
    mains accept experiment names as well as paths."""
    out = []
    for a in argv:
        m = re.fullmatch(r"--config=([A-Za-z_][A-Za-z0-9_]*)(:[A-Za-z0-9_]+)?", a)
        if m:
            a = f"--config={os.path.join(CONFIG_DIR, m.group(1) + '.py')}{m.group(2) or ''}"
        out.append(a)
    return out

"""Every method by one grammar: ``descriptor[@frame][+procedure]``.

A method is a descriptor (``fpfh``, ``shot``, ``spin``, ``usc``, ``lead``, ``lead_pn``,
``sound``), the frame its support is turned into (``flare``, ``shot``'s LRF, ``compass``,
``gt`` — read from a pair's ground truth, a diagnostic) and a procedure run around it (``vote``:
the pair vote of :mod:`sphere_jax.registration.vote`). A descriptor alone means its own frame:
``lead`` is ``lead@flare``, ``shot`` is ``shot@shot``. LRFs are named by their frame alone.

Each :class:`Method` also has a ``key``, the short name the result files, tables and configs
have always used (``lead_compass`` for ``lead@compass``); both spellings are accepted
everywhere (:func:`resolve`), and the files keep the keys so that published runs stay
comparable.

=======================  ================  ==============================================
name                     key               what
=======================  ================  ==============================================
``fpfh``                 ``fpfh``          FPFH (open3d), 33-d, no frame
``shot``                 ``shot``          SHOT, 352-d, in the SHOT LRF
``spin``                 ``spin``          Spin Images, 153-d, about the normal
``usc``                  ``usc``           Unique Shape Context, 1960-d, in the SHOT LRF
``lead@flare``           ``lead``          LEAD's SO(3) map turned to FLARE's frame
``lead@compass``         ``lead_compass``  ... turned to Compass's frame
``lead_pn@flare``        ``lead_pn``       LEAD-PN on FLARE-oriented patches
``sound``                ``sound``         SOUND, self-oriented
``lead@compass+vote``    ``lead_vote``     LEAD in Compass's frames, pair vote, again
``shot+vote``            ``shot_vote``     SHOT in its LRF, pair vote, binned again
``lead@gt``              ``lead_gt``       diagnostic: frames from the ground truth
``shot@gt``              ``shot_gt``       diagnostic: frames from the ground truth
=======================  ================  ==============================================
"""
from __future__ import annotations

import dataclasses

from sphere_jax import checks


@dataclasses.dataclass(frozen=True)
class Method:
    """One descriptor × frame × procedure: its grammar ``name``, the ``key`` files use, the
    bundle kinds it ``needs``, its table ``label`` and what it is (``kind``: ``descriptor``,
    ``voted`` — registration only — or ``diagnostic`` — reads the ground truth)."""
    name: str
    key: str
    needs: tuple[str, ...]
    label: str
    kind: str = "descriptor"
    aliases: tuple[str, ...] = ()       # other spellings: a descriptor's own frame named

    @property
    def learned(self) -> bool:
        return bool(self.needs)


METHODS = (
    Method("fpfh", "fpfh", (), "FPFH"),
    Method("shot", "shot", (), "SHOT", aliases=("shot@shot",)),
    Method("spin", "spin", (), "Spin Images"),
    Method("usc", "usc", (), "USC", aliases=("usc@shot",)),
    Method("lead@flare", "lead", ("lead",), "LEAD (FLARE)"),
    Method("lead@compass", "lead_compass", ("lead", "compass"), "LEAD (Compass)"),
    Method("lead_pn@flare", "lead_pn", ("lead_pn",), "LEAD-PN (FLARE)"),
    Method("sound", "sound", ("sound",), "SOUND"),
    Method("lead@compass+vote", "lead_vote", ("lead", "compass"), "LEAD (Compass) + vote",
           "voted"),
    Method("shot+vote", "shot_vote", (), "SHOT + vote", "voted", ("shot@shot+vote",)),
    Method("lead@gt", "lead_gt", ("lead",), "LEAD (ground-truth frames)", "diagnostic"),
    Method("shot@gt", "shot_gt", (), "SHOT (ground-truth frames)", "diagnostic"),
)

# Local reference frames: (key, bundle kinds needed).
LRFS = {"flare": (), "shot": (), "toldi": (), "3dsn": (), "gframes": (),
        "compass": ("compass",), "sound": ("sound",)}

_BY_SPELLING = {s: m for m in METHODS for s in (m.name, m.key) + m.aliases}


def resolve(name, kinds=("descriptor", "voted", "diagnostic"), argument="method") -> Method:
    """The :class:`Method` a grammar name or key spells (``lead@compass`` or
    ``lead_compass``), among those of ``kinds``; an unknown name is an error naming
    ``argument`` and the choices."""
    method = _BY_SPELLING.get(str(name).strip().lower())
    if method is None or method.kind not in kinds:
        choices = [m.name for m in METHODS if m.kind in kinds]
        raise checks.InputError(argument, f"one of {', '.join(choices)} (or their keys: "
                                f"{', '.join(m.key for m in METHODS if m.kind in kinds)})",
                                repr(name))
    return method


def keys(*kinds) -> tuple[str, ...]:
    """The keys of the methods of ``kinds`` (all when none), in the table order."""
    return tuple(m.key for m in METHODS if not kinds or m.kind in kinds)


def spellings(*kinds) -> tuple[str, ...]:
    """Every accepted spelling of the methods of ``kinds``: grammar names, then keys."""
    chosen = [m for m in METHODS if not kinds or m.kind in kinds]
    return tuple(dict.fromkeys([s for s, m in _BY_SPELLING.items() if m in chosen]))


def needs(key_or_name) -> tuple[str, ...]:
    """Bundle kinds a method or LRF needs."""
    if key_or_name in LRFS:
        return LRFS[key_or_name]
    return resolve(key_or_name).needs


def resamples(key_or_name) -> bool:
    """Whether a method or LRF reads supports resampled to a fixed count
    (:mod:`sphere_jax.data.supports`): the networks and FLARE's frames do; the hand-crafted
    descriptors read exact neighbourhoods."""
    return bool(needs(key_or_name)) or key_or_name == "flare"

"""Every method by one grammar: ``descriptor[@frame][+procedure]``.

A method is a descriptor (``fpfh``, ``shot``, ``spin``, ``usc``, ``lead``, ``lead_pn``,
``sound``), the frame its support is turned into (``flare``, ``shot``'s LRF, ``compass``,
``gt`` — read from a pair's ground truth, a diagnostic) and a procedure run around it (``vote``:
the pair vote of :mod:`sphere_jax.registration.vote`; ``modes``: described under the frame's
strongest modes, :mod:`sphere_jax.features.modes`). A descriptor alone means its own frame:
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
``lead@lrf_net``         ``lead_lrfnet``   ... turned to FLARE's ẑ and a learned x̂
``lead_pn@flare``        ``lead_pn``       LEAD-PN on FLARE-oriented patches
``sound``                ``sound``         SOUND, self-oriented
``lead@compass+modes``   ``lead_modes``    ... under Compass's 3 strongest frames
``lead@compass+vote``    ``lead_vote``     LEAD in Compass's frames, pair vote, again
``shot+vote``            ``shot_vote``     SHOT in its LRF, pair vote, binned again
``lead@gt``              ``lead_gt``       diagnostic: frames from the ground truth
``shot@gt``              ``shot_gt``       diagnostic: frames from the ground truth
=======================  ================  ==============================================
"""
from __future__ import annotations

import dataclasses
from typing import Callable, Optional

from sphere_jax import checks
from sphere_jax.features import builders as b
from sphere_jax.features import lrfs, modes, voted


@dataclasses.dataclass(frozen=True)
class Method:
    """One descriptor × frame × procedure: its grammar ``name``, the ``key`` files use, the
    bundle kinds it ``needs``, its table ``label``, what it is (``kind``: ``descriptor``,
    ``voted`` — registration only — or ``diagnostic`` — reads the ground truth) and what
    builds it (``build``, the contract of its kind in :mod:`~sphere_jax.features.builders`;
    a voted one's in :mod:`~sphere_jax.features.voted`)."""
    name: str
    key: str
    needs: tuple[str, ...]
    label: str
    kind: str = "descriptor"
    aliases: tuple[str, ...] = ()       # other spellings: a descriptor's own frame named
    build: Optional[Callable] = None
    hypotheses: bool = False            # describes under several frames: [K, H, D]

    @property
    def learned(self) -> bool:
        return bool(self.needs)


@dataclasses.dataclass(frozen=True)
class Lrf:
    """A local reference frame: its ``key``, the bundle kinds it ``needs``, and ``build``
    (``build(radius, bundles, chunk) -> orient(fragment, indices) -> [K, 3, 3]``)."""
    key: str
    needs: tuple[str, ...]
    build: Callable


METHODS = (
    Method("fpfh", "fpfh", (), "FPFH", build=b.per_fragment(b.fpfh_of, "fpfh_radius")),
    Method("shot", "shot", (), "SHOT", aliases=("shot@shot",), build=b.per_fragment(b.shot_of)),
    Method("spin", "spin", (), "Spin Images", build=b.per_fragment(b.spin_of)),
    Method("usc", "usc", (), "USC", aliases=("usc@shot",), build=b.per_fragment(b.usc_of)),
    Method("lead@flare", "lead", ("lead",), "LEAD (FLARE)", build=b.network("lead")),
    Method("lead@compass", "lead_compass", ("lead", "compass"), "LEAD (Compass)",
           build=b.network_in_frames_of("lead", "compass")),
    # FLARE's ẑ and a learned x̂: LEAD's whitening of FLARE frames.
    Method("lead@lrf_net", "lead_lrfnet", ("lead", "lrf_net"), "LEAD (learned x̂)",
           build=b.network_in_frames_of("lead", "lrf_net", whitening="default")),
    Method("lead_pn@flare", "lead_pn", ("lead_pn",), "LEAD-PN (FLARE)",
           build=b.network("lead_pn")),
    Method("sound", "sound", ("sound",), "SOUND", build=b.network("sound")),
    Method("lead@compass+modes", "lead_modes", ("lead", "compass"),
           f"LEAD (Compass, {modes.MODES} frame hypotheses)", build=modes.lead_modes,
           hypotheses=True),
    Method("lead@compass+vote", "lead_vote", ("lead", "compass"), "LEAD (Compass) + vote",
           "voted", build=voted.lead_vote),
    Method("shot+vote", "shot_vote", (), "SHOT + vote", "voted", ("shot@shot+vote",),
           build=voted.shot_vote),
    # Whitened as lead@compass is: the two differ by their frames alone.
    Method("lead@gt", "lead_gt", ("lead",), "LEAD (ground-truth frames)", "diagnostic",
           build=b.network_in_one_frame("lead", whiten="compass")),
    Method("shot@gt", "shot_gt", (), "SHOT (ground-truth frames)", "diagnostic",
           build=b.shot_in_one_frame),
)

LRFS = {lrf.key: lrf for lrf in (
    Lrf("flare", (), b.flare_lrf),
    Lrf("shot", (), b.on_neighbourhoods(lrfs.shot_lrf)),
    Lrf("toldi", (), b.on_neighbourhoods(lrfs.toldi_lrf)),
    Lrf("3dsn", (), b.on_neighbourhoods(lrfs.threedsn_lrf)),
    Lrf("gframes", (), b.on_neighbourhoods(lrfs.gframes_lrf, with_normals=True)),
    Lrf("compass", ("compass",), b.network_lrf("compass")),
    Lrf("lrf_net", ("lrf_net",), b.network_lrf("lrf_net")),
    Lrf("sound", ("sound",), b.network_lrf("sound")),
)}


def _by_spelling() -> dict:
    # Read from the table at each call: a test that adds a row (monkeypatch) sees it here.
    return {s: m for m in METHODS for s in (m.name, m.key) + m.aliases}


def resolve(name, kinds=("descriptor", "voted", "diagnostic"), argument="method") -> Method:
    """The :class:`Method` a grammar name or key spells (``lead@compass`` or
    ``lead_compass``), among those of ``kinds``; an unknown name is an error naming
    ``argument`` and the choices."""
    method = _by_spelling().get(str(name).strip().lower())
    if method is None or method.kind not in kinds:
        choices = [m.name for m in METHODS if m.kind in kinds]
        raise checks.InputError(argument, f"one of {', '.join(choices)} (or their keys: "
                                f"{', '.join(m.key for m in METHODS if m.kind in kinds)})",
                                repr(name))
    return method


def keys(*kinds, learned=None) -> tuple[str, ...]:
    """The keys of the methods of ``kinds`` (all when none), in the table order; with
    ``learned`` True or False, only those that read a network or only those that do not."""
    return tuple(m.key for m in METHODS if (not kinds or m.kind in kinds)
                 and (learned is None or m.learned == learned))


def spellings(*kinds) -> tuple[str, ...]:
    """Every accepted spelling of the methods of ``kinds``: grammar names, then keys."""
    chosen = [m for m in METHODS if not kinds or m.kind in kinds]
    return tuple(dict.fromkeys([s for s, m in _by_spelling().items() if m in chosen]))


def needs(key_or_name) -> tuple[str, ...]:
    """Bundle kinds a method or LRF needs."""
    if key_or_name in LRFS:
        return LRFS[key_or_name].needs
    return resolve(key_or_name).needs


def resamples(key_or_name) -> bool:
    """Whether a method or LRF reads supports resampled to a fixed count
    (:mod:`sphere_jax.data.supports`): the networks and FLARE's frames do; the hand-crafted
    descriptors read exact neighbourhoods."""
    return bool(needs(key_or_name)) or key_or_name == "flare"

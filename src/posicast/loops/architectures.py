"""Where the shaper sits: the registry of loop architectures (seed 001 Fig. 1-3).

An architecture is a name and a function building the loop's
:class:`~posicast.loops.ring.Ring` from its blocks (:class:`LoopBlocks`).
Every loop has the actuator-side plant ``G``, the flexible load ``F`` (outside
the loop, ``y = F z``), the controller ``C`` and a shaper ``S``; four external
inputs act on it: ``w`` reference, ``d`` output disturbance (added to the
actuator output ``z``), ``di`` input disturbance (added to the plant input),
``n`` measurement noise (added to the measured ``z``).

=================  =================================================================
architecture       signal equations
=================  =================================================================
feedforward        ``r = S w``; ``e = r - (z + n)``; ``v = C e``; ``u = v``;
(seed 001 Fig. 1)  ``z = G (u + di) + d``; ``y = F z``
control_action     ``e = w - (z + n)``; ``v = C e``; ``u = S v``;
(Fig. 2, "CLSS")   ``z = G (u + di) + d``; ``y = F z``
inverse_shaper     ``e = w - m``, ``m = (z + n) / S``; ``v = C e``; ``u = v``;
(Fig. 3)           ``z = G (u + di) + d``; ``y = F z``
model_matching     as control_action, with ``G`` the inner closed loop
(seed 003 Fig. 1)  ``P G_i F_i / (1 + P G_i)`` (``u = r_s``, the shaped inner reference);
                   built by :func:`posicast.qft.model_matching`
=================  =================================================================

Adding an architecture is one call of :func:`register_architecture`; the loop
(:class:`~posicast.loops.Loop`), its channels and the simulator
(:func:`posicast.simulate`) read the ring and need nothing else.

>>> "control_action" in ARCHITECTURES, len(ARCHITECTURES) >= 3
(True, True)
"""

from __future__ import annotations

from typing import Callable, Iterator, Sequence

from .. import _validate as v
from .ring import IDENTITY, LoopBlocks, Ring, Tap

__all__ = ["ARCHITECTURES", "INPUTS", "register_architecture", "unregister_architecture", "ring_builder"]

INPUTS = ("w", "d", "di", "n")

RingBuilder = Callable[[LoopBlocks], Ring]


def _standard_ring(blocks: LoopBlocks, *, reference: Tap, shaper_after_controller: bool,
                   inverse_feedback: bool) -> Ring:
    """``e -> v -> u -> up -> z -> zn (-> m)``: the ring the three seed architectures share."""
    S = blocks.S if shaper_after_controller else IDENTITY
    nodes = ("e", "v", "u", "up", "z", "zn") + (("m",) if inverse_feedback else ())
    ring_blocks = (IDENTITY, blocks.C, S, IDENTITY, blocks.G, IDENTITY) + ((blocks.S_inverse,) if inverse_feedback else ())
    idx = {name: i for i, name in enumerate(nodes)}
    inputs = {"w": reference, "d": Tap(idx["z"]), "di": Tap(idx["up"]), "n": Tap(idx["zn"])}
    outputs = {name: Tap(idx[name]) for name in ("e", "v", "u", "z")}
    outputs["y"] = Tap(idx["z"], blocks.F)
    if inverse_feedback:
        outputs["m"] = Tap(idx["m"])
    return Ring(nodes, ring_blocks, inputs, outputs)


def _feedforward(blocks: LoopBlocks) -> Ring:
    ring = _standard_ring(blocks, reference=Tap(0, blocks.S), shaper_after_controller=False, inverse_feedback=False)
    return Ring(ring.nodes, ring.blocks, ring.inputs, ring.outputs, external={"r": "w"})


def _control_action(blocks: LoopBlocks) -> Ring:
    return _standard_ring(blocks, reference=Tap(0), shaper_after_controller=True, inverse_feedback=False)


def _inverse_shaper(blocks: LoopBlocks) -> Ring:
    return _standard_ring(blocks, reference=Tap(0), shaper_after_controller=False, inverse_feedback=True)


def _model_matching(blocks: LoopBlocks) -> Ring:
    """Seed 003 Fig. 1: the shaper before the inner model-matching loop, which is the block ``G``."""
    return _control_action(blocks)


_REGISTRY: dict[str, RingBuilder] = {
    "feedforward": _feedforward,
    "control_action": _control_action,
    "inverse_shaper": _inverse_shaper,
    "model_matching": _model_matching,
}
_BUILTIN = tuple(_REGISTRY)


class _ArchitectureNames(Sequence[str]):
    """The registered architecture names, live: iterates, tests membership and prints like a tuple."""

    def __getitem__(self, i):  # type: ignore[no-untyped-def]
        return tuple(_REGISTRY)[i]

    def __len__(self) -> int:
        return len(_REGISTRY)

    def __iter__(self) -> Iterator[str]:
        return iter(tuple(_REGISTRY))

    def __contains__(self, name: object) -> bool:
        return isinstance(name, str) and name in _REGISTRY

    def __eq__(self, other: object) -> bool:
        return tuple(self) == (tuple(other) if isinstance(other, (tuple, list, _ArchitectureNames)) else other)

    def __hash__(self) -> int:
        return hash(tuple(self))

    def __repr__(self) -> str:
        return repr(tuple(_REGISTRY))


ARCHITECTURES: Sequence[str] = _ArchitectureNames()


def register_architecture(name: str, build: RingBuilder, *, replace: bool = False) -> None:
    """Add an architecture: ``build(blocks)`` returns the :class:`~posicast.loops.ring.Ring` of a loop.

    Parameters
    ----------
    name : str
        The architecture's name (``Loop(name, G=..., C=..., ...)``).
    build : callable
        ``build(LoopBlocks(G, C, F, S, S_inverse)) -> Ring``; the ring must take the
        inputs ``w, d, di, n``.
    replace : bool
        Allow replacing a registered architecture other than the seeds' own.

    Examples
    --------
    A shaper in the feedback path, ``e = w - S (z + n)``:

    >>> from posicast.loops.ring import IDENTITY, Ring, Tap
    >>> def feedback_shaper(b):
    ...     nodes = ("e", "v", "up", "z", "zn", "m")
    ...     return Ring(nodes, (IDENTITY, b.C, IDENTITY, b.G, IDENTITY, b.S),
    ...                 {"w": Tap(0), "di": Tap(2), "d": Tap(3), "n": Tap(4)},
    ...                 {"e": Tap(0), "v": Tap(1), "u": Tap(1), "z": Tap(3), "y": Tap(3, b.F), "m": Tap(5)})
    >>> register_architecture("feedback_shaper", feedback_shaper)
    >>> "feedback_shaper" in ARCHITECTURES
    True
    >>> unregister_architecture("feedback_shaper")
    """
    if not isinstance(name, str) or not name:
        raise TypeError(f"name must be a non-empty string, got {name!r}")
    if not callable(build):
        raise TypeError(f"build must be a callable returning a Ring, got {type(build).__name__}")
    if not isinstance(replace, bool):
        raise TypeError(f"replace must be a bool, got {type(replace).__name__}")
    if name in _BUILTIN or (name in _REGISTRY and not replace):
        raise ValueError(f"name must not be a registered architecture {tuple(_REGISTRY)}"
                         f"{' (the seeds cannot be replaced)' if name in _BUILTIN else ''}, got {name!r}")
    _REGISTRY[name] = build


def unregister_architecture(name: str) -> None:
    """Remove an architecture added by :func:`register_architecture` (the seeds' own stay)."""
    v.choice(name, "name", tuple(n for n in _REGISTRY if n not in _BUILTIN))
    del _REGISTRY[name]


def ring_builder(name: str) -> RingBuilder:
    """The function building the ring of architecture ``name``."""
    if not isinstance(name, str):
        raise TypeError(f"architecture must be a string, got {type(name).__name__}")
    if name not in _REGISTRY:
        raise ValueError(f"architecture must be one of {ARCHITECTURES}, got {name!r}")
    return _REGISTRY[name]


def build_ring(name: str, blocks: LoopBlocks) -> Ring:
    """The ring of architecture ``name`` for ``blocks``, checked to take the inputs ``w, d, di, n``."""
    ring = ring_builder(name)(blocks)
    if not isinstance(ring, Ring):
        raise TypeError(f"the {name} architecture must build a Ring, got {type(ring).__name__}")
    if tuple(sorted(ring.inputs)) != tuple(sorted(INPUTS)):
        raise ValueError(f"the {name} ring must take the inputs {INPUTS}, got {tuple(ring.inputs)}")
    return ring

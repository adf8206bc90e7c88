"""The loop's ring as the simulator reads it (:class:`~posicast.loops.ring.Ring`).

The simulator never asks for an architecture's name: it reads where the
controller ``C``, the plant ``G`` and the shaper (``S`` or ``1/S``) sit in the
ring, and which inputs are added where.  The ring's nodes fall in four
segments, by where an input added there acts:

* **reference side**, nodes ``0 .. c - 1`` (``c`` the controller's block):
  enters the controller with the sign +1 (``w`` at the comparator);
* **plant input**, nodes ``c .. g - 1`` (``g`` the plant's block): enters ``G`` (``di``);
* **plant output**, node ``g``: added to ``G``'s output and seen by the load ``F`` (``d``);
* **feedback**, nodes ``g + 1 ..``: enters the controller with the sign -1 (``n``).

Every other block of the ring is a plain connection, but for at most one shaper
block; ``w`` may enter through the shaper outside the loop (feedforward).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..loops.ring import INVERSE_SHAPER, SHAPER, Ring

if TYPE_CHECKING:
    from ..loops.loop import Loop

__all__ = ["RingLayout", "read_ring"]

Signals = dict[str, np.ndarray]


@dataclass(frozen=True)
class RingLayout:
    """Where the blocks of a loop's ring sit, for the simulator.

    Attributes
    ----------
    ring : Ring
    controller, plant : int
        Ring indices of the blocks ``C`` and ``G`` (``0 < controller < plant``).
    shaper : int or None
        Ring index of the shaper block (``S`` or ``1/S``), None when it is outside the loop or absent.
    inverse : bool
        The ring's shaper block is ``1/S`` (``S m = (its input)``).
    reference_shaper : bool
        The reference ``w`` enters through the shaper ``S`` (outside the loop).
    load_node : int
        The node read by ``y`` through ``F`` (the plant's output node).
    """

    ring: Ring
    controller: int
    plant: int
    shaper: int | None
    inverse: bool
    reference_shaper: bool

    @property
    def load_node(self) -> int:
        return self.plant

    @property
    def nodes(self) -> tuple[str, ...]:
        return self.ring.nodes

    def segment(self, node: int) -> str:
        """``'reference'``, ``'plant input'``, ``'plant output'`` or ``'feedback'`` (module docstring)."""
        if node < self.controller:
            return "reference"
        if node < self.plant:
            return "plant input"
        return "plant output" if node == self.plant else "feedback"

    def injected(self, sig: Signals, node: int) -> np.ndarray | None:
        """The sum of the inputs added at ``node`` (``w`` as given: its prefilter is applied by the caller)."""
        names = self.ring.injected(node)
        if not names:
            return None
        out = sig[names[0]]
        for name in names[1:]:
            out = out + sig[name]
        return out

    def held_sum(self, sig: Signals, segment: str) -> np.ndarray | None:
        """Sum of the inputs of one segment, walking the ring backwards (the feedback path's order)."""
        out = None
        for node in range(len(self.nodes) - 1, -1, -1):
            if self.segment(node) != segment:
                continue
            for name in self.ring.injected(node):
                out = sig[name] if out is None else out + sig[name]
        return out

    def controller_input(self, sig: Signals, r: np.ndarray) -> np.ndarray:
        """``ext``: the controller's input less the plant's state output, ``r - (feedback, then plant output, inputs)``."""
        ext = r
        for seg in ("reference", "feedback", "plant output"):
            for node in range(len(self.nodes) - 1, -1, -1):
                if self.segment(node) != seg:
                    continue
                for name in self.ring.injected(node):
                    if name == "w":
                        continue
                    ext = ext + sig[name] if seg == "reference" else ext - sig[name]
        return ext

    def walk(self, known: Signals, sig: Signals, r: np.ndarray | None = None) -> Signals:
        """Fill every node that follows a known node through a plain connection: ``node = previous + inputs``.

        The comparator (node 0) is ``(inputs at e) - (plant output) - (feedback inputs)`` when the
        feedback path is plain; ``r`` is the (shaped) reference that enters at its node.
        """
        n = len(self.nodes)
        val = {self.nodes[i]: known[self.nodes[i]] for i in range(n) if self.nodes[i] in known}
        for _ in range(2):  # twice round the ring reaches every node after a known one
            for i in range(n):
                name = self.nodes[i]
                if name in val or not self.ring.blocks[i].identity:
                    continue
                if i == 0:
                    if self.shaper is not None and self.shaper > self.plant:
                        continue
                    if self.nodes[self.plant] not in val:
                        continue
                    out = self._reference(sig, r, 0) - val[self.nodes[self.plant]]
                    for node in range(self.plant + 1, n):
                        for src in self.ring.injected(node):
                            out = out - sig[src]
                    val[name] = out
                    continue
                prev = self.nodes[i - 1]
                if prev not in val:
                    continue
                add = self._reference(sig, r, i) if self.ring.injected(i) else None
                val[name] = val[prev] if add is None else val[prev] + add
        return val

    def _reference(self, sig: Signals, r: np.ndarray | None, node: int) -> np.ndarray:
        out = None
        for src in self.ring.injected(node):
            x = r if (src == "w" and r is not None) else sig[src]
            out = x if out is None else out + x
        return out if out is not None else np.zeros_like(next(iter(sig.values())))

    def outputs(self, nodes: Signals, y: np.ndarray, r: np.ndarray | None) -> Signals:
        """The response's signals: every node but ``zn``-like hidden ones is kept, plus outputs and ``y``."""
        out = dict(nodes)
        for name, tap in self.ring.outputs.items():
            if name == "y":
                out["y"] = y
            elif tap.block.identity:
                out.setdefault(name, nodes[self.nodes[tap.node]])
        for name in self.ring.external:
            out[name] = r
        return out


def read_ring(loop: Loop) -> RingLayout:
    """The simulator's reading of ``loop.ring``; ValueError for a ring it cannot run."""
    ring = loop.ring
    names = [b.name for b in ring.blocks]
    arch = loop.architecture

    def refuse(why: str) -> ValueError:
        return ValueError(f"simulation of the {arch} loop: {why}")

    if names.count("C") != 1 or names.count("G") != 1:
        raise refuse("its ring must hold one controller C and one plant G")
    c, g = names.index("C"), names.index("G")
    if not 0 < c < g:
        raise refuse("the controller C must come before the plant G in its ring (after the comparator)")
    shaped = [i for i, b in enumerate(ring.blocks) if b.name in (SHAPER, INVERSE_SHAPER) and not b.identity]
    if len(shaped) > 1:
        raise refuse("at most one shaper block can sit in its ring")
    for i, b in enumerate(ring.blocks):
        if i not in (c, g) and i not in shaped and not b.identity:
            raise refuse(f"block {b.name!r} must be C, G, the shaper or a plain connection")
    if not ring.blocks[0].identity:
        raise refuse("the comparator (block 0) must be a plain connection")
    ref_shaper = _check_taps(ring, g, bool(shaped), refuse)
    shaper = shaped[0] if shaped else None
    inverse = shaper is not None and ring.blocks[shaper].name == INVERSE_SHAPER
    return RingLayout(ring, c, g, shaper, inverse, ref_shaper)


def _check_taps(ring: Ring, g: int, shaper_in_ring: bool, refuse: Callable[[str], ValueError]) -> bool:
    """Inputs enter without a block but ``w`` through ``S``; ``y`` reads ``G``'s output through ``F``.

    Returns True when ``w`` enters through the shaper (outside the loop).
    """
    ref_shaper = False
    for name, tap in ring.inputs.items():
        if tap.block.identity:
            continue
        if name != "w" or tap.block.name != SHAPER or shaper_in_ring:
            raise refuse(f"input {name!r} must enter without a block (only w may pass the shaper, "
                         f"when no shaper is in the ring)")
        ref_shaper = True
    for name, tap in ring.outputs.items():
        if name == "y":
            if tap.node != g or tap.block.name != "F":
                raise refuse("y must read the plant's output through F")
        elif not tap.block.identity:
            raise refuse(f"output {name!r} must read its node without a block")
    return ref_shaper

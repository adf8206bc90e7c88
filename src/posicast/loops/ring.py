"""The ring of a loop: its blocks and how they connect (seed 001 Fig. 1-3).

A loop is a **ring** of signals ``nodes[0], nodes[1], ...``: node 0 is the
comparator output ``e``, and block ``i`` maps node ``i - 1`` to node ``i``
(block 0 closes the ring: ``e = (inputs at e) - nodes[-1]``, the comparator's
sign -1).  An external input is added at one node, through its own block (a
prefilter outside the loop, e.g. the feedforward shaper on ``w``); an output
reads one node, through its own block (``F`` for the load ``y``).  So every
node obeys

``nodes[i] = blocks[i] nodes[i - 1] + sum of (prefilter x input) added at i``

with ``blocks[0] nodes[-1]`` entering with the sign -1.  Outputs outside the
loop (the feedforward architecture's shaped reference ``r = S w``) are an
input's prefiltered signal: :attr:`Ring.external`.

Blocks are named for what they are; :class:`~posicast.loops.Loop` and the
simulator (:mod:`posicast.simulation`) read the names ``"C"`` (controller),
``"G"`` (actuator-side plant), ``"F"`` (flexible load), ``"S"`` (the shaper),
``"1/S"`` (the inverse shaper) and ``"1"`` (a plain connection).

>>> ring = Ring(nodes=("e", "v", "z"), blocks=(IDENTITY, Block("C"), Block("G")),
...             inputs={"w": Tap(0), "d": Tap(2), "di": Tap(1), "n": Tap(2)}, outputs={"z": Tap(2)})
>>> ring.path("w", "z").nodes                  # w at e, through v, to z
frozenset({1, 2})
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Mapping, NamedTuple

from .. import _validate as v
from ..core.quasipoly import QuasiPolynomial
from ..core.transfer import TransferFunction

__all__ = ["Block", "IDENTITY", "Tap", "Path", "Ring", "LoopBlocks", "SHAPER", "INVERSE_SHAPER"]

SHAPER = "S"
INVERSE_SHAPER = "1/S"


@dataclass(frozen=True)
class Block:
    """One block ``N / D`` of a ring; ``num = den = None`` is the identity (a plain connection).

    Attributes
    ----------
    name : str
        What the block is: ``"C"``, ``"G"``, ``"F"``, ``"S"``, ``"1/S"`` or ``"1"``.
    num, den : QuasiPolynomial or None
        Numerator and denominator (both None for the identity).
    """

    name: str
    num: QuasiPolynomial | None = None
    den: QuasiPolynomial | None = None

    @property
    def identity(self) -> bool:
        """True for a plain connection (no dynamics)."""
        return self.num is None

    @classmethod
    def of(cls, name: str, tf: TransferFunction) -> Block:
        """The block ``tf`` named ``name``."""
        return cls(name, tf.num, tf.den)

    @classmethod
    def inverse_of(cls, name: str, tf: TransferFunction) -> Block:
        """The block ``1 / tf`` named ``name`` (numerator and denominator swapped)."""
        return cls(name, tf.den, tf.num)


IDENTITY = Block("1")


class Tap(NamedTuple):
    """Where an input enters a ring or an output reads it: a node, through a block outside the loop."""

    node: int
    block: Block = IDENTITY


class Path(NamedTuple):
    """The way from an input to an output: its own two blocks, the ring nodes passed and the sign.

    ``sign`` is -1 when the path crosses the comparator (passes node 0).
    """

    pre: Block
    post: Block
    nodes: frozenset[int]
    sign: float


class LoopBlocks(NamedTuple):
    """The blocks an architecture arranges: ``S`` and ``S_inverse`` are the identity without a shaper."""

    G: Block
    C: Block
    F: Block
    S: Block
    S_inverse: Block


@dataclass(frozen=True)
class Ring:
    """The signal equations of a loop (see the module docstring).

    Attributes
    ----------
    nodes : tuple of str
        The loop's signals in ring order; ``nodes[0]`` is the comparator output ``e``.
    blocks : tuple of Block
        ``blocks[i]`` maps ``nodes[i - 1]`` to ``nodes[i]``; ``blocks[0]`` is the comparator (sign -1).
    inputs : mapping of str to Tap
        Input name -> the node where it is added, through its prefilter.
    outputs : mapping of str to Tap
        Output name -> the node it reads, through its postfilter.
    external : mapping of str to str
        Outputs outside the loop: name -> the input whose prefiltered signal it is (``{"r": "w"}``).
    """

    nodes: tuple[str, ...]
    blocks: tuple[Block, ...]
    inputs: Mapping[str, Tap]
    outputs: Mapping[str, Tap]
    external: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        nodes = tuple(v.sequence(self.nodes, "nodes"))
        blocks = tuple(v.sequence(self.blocks, "blocks"))
        if len(nodes) < 2 or len(blocks) != len(nodes):
            raise ValueError(f"blocks must have one block per node (at least 2), got {len(blocks)} blocks for "
                             f"{len(nodes)} nodes")
        if len(set(nodes)) != len(nodes) or not all(isinstance(n, str) for n in nodes):
            raise ValueError(f"nodes must be distinct strings, got {nodes!r}")
        for i, b in enumerate(blocks):
            if not isinstance(b, Block):
                raise TypeError(f"blocks[{i}] must be a Block, got {type(b).__name__}")
        taps = {}
        for kind in ("inputs", "outputs"):
            table = {}
            for name, tap in dict(getattr(self, kind)).items():
                tap = Tap(*tap) if isinstance(tap, tuple) else tap
                if not isinstance(tap, Tap) or not isinstance(tap.block, Block):
                    raise TypeError(f"{kind}[{name!r}] must be a Tap(node, block), got {tap!r}")
                v.integer_in_range(tap.node, f"{kind}[{name!r}].node", 0, len(nodes) - 1)
                table[name] = tap
            taps[kind] = table
        external = dict(self.external)
        for name, src in external.items():
            v.choice(src, f"external[{name!r}]", tuple(taps["inputs"]))
        clash = set(taps["outputs"]) & set(external)
        if clash:
            raise ValueError(f"external outputs must not repeat ring outputs, got {sorted(clash)}")
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "blocks", blocks)
        object.__setattr__(self, "inputs", MappingProxyType(taps["inputs"]))
        object.__setattr__(self, "outputs", MappingProxyType(taps["outputs"]))
        object.__setattr__(self, "external", MappingProxyType(external))

    def index(self, name: str) -> int:
        """Position of the first block named ``name`` in the ring, or -1."""
        return next((i for i, b in enumerate(self.blocks) if b.name == name), -1)

    def has_shaper(self) -> bool:
        """True if the shaper (``S`` or ``1/S``, not the identity) is a block of the ring."""
        return any(b.name in (SHAPER, INVERSE_SHAPER) and not b.identity for b in self.blocks)

    def path(self, src: str, dst: str) -> Path:
        """The ring's blocks on the way from input ``src`` to ring output ``dst``."""
        n_nodes = len(self.nodes)
        a, pre = self.inputs[src]
        b, post = self.outputs[dst]
        length = (b - a) % n_nodes
        nodes = frozenset((a + k) % n_nodes for k in range(1, length + 1))
        return Path(pre, post, nodes, -1.0 if 0 in nodes else 1.0)

    def injected(self, node: int) -> tuple[str, ...]:
        """Names of the inputs added at ``node``."""
        return tuple(name for name, tap in self.inputs.items() if tap.node == node)

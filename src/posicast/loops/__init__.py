"""Stage 4: feedback loops with a signal shaper (seed 001 Fig. 1-3, seed 000 Sec. III-V).

>>> import posicast
>>> loop = posicast.inverse_shaper(G=(1, [1, 1, 0]), C=([10, 10], [0.01, 1]),
...                                S=posicast.design("dzv", posicast.Mode(10.0, 0.03)))
>>> loop.architecture, loop.inputs
('inverse_shaper', ('w', 'd', 'di', 'n'))
>>> loop.ring.nodes                 # its ring of signals (posicast.loops.ring)
('e', 'v', 'u', 'up', 'z', 'zn', 'm')
"""

from .loop import (
    ARCHITECTURES,
    INPUTS,
    Loop,
    Margins,
    NyquistResponse,
    control_action,
    feature_frequencies,
    feedforward,
    inverse_shaper,
    removable_points,
)
from .architectures import register_architecture, unregister_architecture
from .plots import bode_plot, nyquist_plot, spectrum_plot
from .ring import Block, LoopBlocks, Ring, Tap

__all__ = [
    "Loop", "feedforward", "control_action", "inverse_shaper", "Margins", "NyquistResponse",
    "ARCHITECTURES", "INPUTS", "removable_points", "feature_frequencies", "bode_plot", "nyquist_plot", "spectrum_plot",
    "Ring", "Block", "Tap", "LoopBlocks", "register_architecture", "unregister_architecture",
]

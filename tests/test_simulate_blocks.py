"""Issue #15 (part B): the shaper-in-the-loop simulation by blocks and in chunks.

The block method (kernels as running sums, :mod:`posicast.simulation.running_sums`)
against the step-by-step update of the same discrete loop, a chunked run against
one run over the whole grid, and the ``outputs=`` selection.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

import posicast
from posicast.shapers.base import DistributedPart, Kernel, Shaper
from posicast.simulation import shaped_loop, stepped
from posicast.simulation.running_sums import running_sums
from posicast.simulation.streaming import discretize

MODE = posicast.Mode(10.0, 0.03)  # seed 000 eq. 25-27
G = ([1.0], [1.0, 1.0, 0.0])
F = ([1.0, 0.0], [1.0, 0.6, 100.0])
C = ([10.0, 10.0], [0.01, 1.0])


def _kernel_shaper(shape: str, delay: float = 0.0) -> Shaper:
    """Half an impulse at 0 and half a kernel of length 0.3 s (from ``delay``)."""
    return Shaper([0.0], [0.5], (DistributedPart(0.5, delay, (Kernel(shape, 0.3),)),), name=f"test {shape}")


def _delayed(S: Shaper, h: float) -> tuple[np.ndarray, int]:
    taps = np.asarray(discretize(S, 1.0 / h, "linear").taps)
    first = int(np.flatnonzero(taps[1:])[0]) + 1
    return taps[first:], first


@pytest.mark.parametrize("shape, order", [("uniform", 1), ("triangular", 2), ("decreasing", 2)])
def test_running_sums_give_back_the_taps(shape, order):
    """D q = R xs: the recursion's impulse response is the discretised kernel's taps, and zero after them."""
    S = _kernel_shaper(shape)
    delayed, first = _delayed(S, 1e-3)
    plan = running_sums(S, delayed, first)
    assert plan is not None and plan.order == order
    assert plan.far.size <= 8 and plan.block > 100  # a few taps at the breakpoints, far from the head
    coef = np.zeros(int(plan.far[-1]) + 1)
    coef[plan.head] = plan.head_coef
    coef[plan.far] = plan.far_coef
    impulse = np.zeros(delayed.size + first + 200)
    impulse[0] = 1.0
    want = np.zeros(impulse.size)
    want[first: first + delayed.size] = delayed
    # rounding of the annihilated interior drifts after the kernel (a ramp of 1e-16): the reason for the
    # exact restart of every block
    assert np.max(np.abs(signal.lfilter(coef, plan.den, impulse) - want)) < 1e-12 * np.max(delayed)


def test_cosine_kernel_and_lumped_shapers_keep_their_taps():
    """No recursion for a cosine kernel (ill-conditioned: three roots near z = 1) or without kernels."""
    for S in (_kernel_shaper("cosine"), posicast.design("zvd", MODE)):
        delayed, first = _delayed(S, 1e-3)
        assert running_sums(S, delayed, first) is None


@pytest.mark.parametrize("arch", ["inverse_shaper", "control_action"])
@pytest.mark.parametrize("kind", ["dzv", "triangular", "decreasing"])
def test_blocks_equal_the_step_by_step_update(arch, kind, monkeypatch):
    """Kernels from t = 0 (the history enters every step): the block method equals one update per step."""
    S = posicast.design("dzv", MODE) if kind == "dzv" else _kernel_shaper(kind)
    loop = getattr(posicast, arch)(G=G, F=F, C=C, S=S)
    t = np.arange(0.0, 4.0, 1e-3)
    kw = {"w": (t >= 0.2).astype(float), "d": 0.3 * (t >= 1.1), "di": 0.1 * (t >= 1.7), "n": 1e-3 * np.sin(40 * t)}
    blocks = posicast.simulate(loop, t, **kw)
    monkeypatch.setattr(shaped_loop, "_BLOCK_MIN", 10**9)
    steps = posicast.simulate(loop, t, **kw)
    for key in ("y", "z", "u", "e", "v"):
        scale = np.max(np.abs(steps.signals[key]))
        assert np.max(np.abs(blocks.signals[key] - steps.signals[key])) < 1e-10 * scale  # as tests/test_simulate.py
    assert abs(blocks.accuracy - steps.accuracy) < 1e-10 * np.max(np.abs(steps.y))  # a difference of two y


@pytest.mark.parametrize("substeps", [1, 2, 3])
def test_chunks_equal_one_run(substeps, monkeypatch):
    """The run carried over many chunks (states, history, load filter) equals one run over the whole grid."""
    loop = posicast.inverse_shaper(G=G, F=F, C=C, S=posicast.design("dzv", MODE))
    t = np.arange(0.0, 6.0, 2e-3)
    kw = {"w": (t >= 0.5).astype(float), "d": 0.2 * (t >= 3.0)}
    one = posicast.simulate(loop, t, substeps=substeps, **kw)
    monkeypatch.setattr(stepped, "CHUNK", 997)  # chunks that split the kernel and the blocks anywhere
    many = posicast.simulate(loop, t, substeps=substeps, **kw)
    assert set(one.signals) == set(many.signals)
    for key, values in one.signals.items():
        assert np.max(np.abs(many.signals[key] - values)) <= 1e-12 * max(1.0, np.max(np.abs(values)))
    assert abs(many.accuracy - one.accuracy) < 1e-12 * np.max(np.abs(one.y))


def test_outputs_keep_the_signals_asked_for():
    loop = posicast.inverse_shaper(G=G, F=F, C=C, S=posicast.design("dzv", MODE))
    t = np.arange(0.0, 3.0, 1e-3)
    w = (t >= 0.5).astype(float)
    full = posicast.simulate(loop, t, w=w)
    part = posicast.simulate(loop, t, w=w, outputs=("y", "u"))
    assert sorted(part.signals) == ["u", "w", "y"]
    assert np.array_equal(part.y, full.y) and np.array_equal(part.u, full.u) and part.accuracy == full.accuracy
    sampled = posicast.simulate(loop, t, w=w, n=0 * w, sample_rate=1000.0, outputs="m")
    assert sorted(sampled.signals) == ["m", "n", "w"]


@pytest.mark.parametrize("bad, exc, word", [
    (("y", "q"), ValueError, "outputs must be one of"),
    (("zn",), ValueError, "outputs must be one of"),
    ((), ValueError, "outputs"),
    ((3,), TypeError, "outputs"),
    (5, TypeError, "outputs must be a sequence"),
])
def test_outputs_refused_with_their_name(bad, exc, word):
    loop = posicast.inverse_shaper(G=G, F=F, C=C, S=posicast.design("dzv", MODE))
    t = np.arange(0.0, 1.0, 1e-3)
    with pytest.raises(exc, match=word):
        posicast.simulate(loop, t, w=np.ones_like(t), outputs=bad)


def test_memory_limit_charges_the_in_loop_run_for_what_it_keeps():
    """Two hours at 1 kHz: refused for the exact method (every signal and temporaries, ~350 B per sample),
    accepted for the shaper-in-the-loop run, which works in chunks (at most 12 signals kept, 96 B)."""
    from posicast.simulation.checks import refuse_work
    from posicast.simulation.layout import read_ring

    n = 7_200_000
    S = posicast.design("dzv", MODE)
    inside = posicast.inverse_shaper(G=G, F=F, C=C, S=S)
    refuse_work(read_ring(inside), S, n, 1e-3, None, None, False)  # no refusal
    outside = posicast.feedforward(G=G, F=F, C=C, S=S)
    with pytest.raises(ValueError, match=r"simulating 7\.2e\+06 samples would need about 2\.52 GB"):
        refuse_work(read_ring(outside), S, n, 1e-3, None, None, False)

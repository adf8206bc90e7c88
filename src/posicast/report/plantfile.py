"""The plant file of ``posicast report``: a small JSON description of a loop to analyse.

Only ``plant`` is required::

    {
      "name": "seed 003 two-mass plant",
      "plant": {"num": [0.1, 10], "den": [10, 51.1, 115, 500, 0], "delay": 0.0},
      "load": {"num": [1], "den": [1]},
      "controller": {"num": [9.504, 0.396], "den": [1, 0]},
      "mode": {"freq_hz": 0.5105, "zeta": 0.0389},
      "shaper": {"kind": "zvdk", "k": 2},
      "architecture": "control_action",
      "tune": {"controller": "pi", "ms": 1.4},
      "horizon": 60
    }

Polynomials are in descending powers of ``s`` (numpy's order), ``delay`` a dead time in
seconds.  ``plant`` is ``G`` (``z = G u``, inside the loop), ``load`` the flexible part
outside it (``y = F z``, default 1), ``controller`` your ``C`` (optional: without it only
the tuned controllers are shown).  ``mode`` (``freq_hz`` or ``omega``, and ``zeta``) is the
mode the shaper cancels; by default the least damped complex pole pair of ``load``, else of
``plant``.  ``shaper`` is a kind of :func:`posicast.design` (a string, or an object with
``kind`` and its parameters; default ``"zvd"``), ``architecture`` where it sits
(``control_action``, ``inverse_shaper`` or ``feedforward``; default ``control_action``),
``tune`` the controller to design (``"pd"`` or ``"pi"``, peak sensitivity ``ms``; default
``{"controller": "pi", "ms": 1.4}``) and ``horizon`` the simulated time in seconds (default:
about 40 periods of the mode).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

from .. import _validate as v
from ..cases import modes_of
from ..core.transfer import TransferFunction
from ..modes import Mode
from ..shapers.registry import KINDS

__all__ = ["PlantSpec", "load_plant", "plant_spec", "ARCHITECTURES", "KEYS"]

ARCHITECTURES = ("control_action", "inverse_shaper", "feedforward")
#: The keys a plant file may have.
KEYS = ("name", "plant", "load", "controller", "mode", "shaper", "architecture", "tune", "horizon")
#: Simulated time in periods of the mode when the file gives no ``horizon``; and its bounds [s].
HORIZON_PERIODS = 40.0
MAX_SAMPLES = 200_000


@dataclass(frozen=True)
class PlantSpec:
    """A checked plant file.

    Attributes
    ----------
    name : str
    G, F : TransferFunction
        Plant (inside the loop) and load (outside it; 1 when not given).
    C : TransferFunction or None
        The user's controller.
    mode : Mode
        The mode the shaper cancels.
    mode_source : str
        Where ``mode`` comes from ("the file", "the load's least damped poles", ...).
    shaper : str
        A kind of :func:`posicast.design`; ``shaper_params`` its parameters.
    architecture : str
    controller : str
        ``"pd"`` or ``"pi"``: the controller to tune; ``ms`` its peak-sensitivity bound.
    horizon : float
        Simulated time [s].
    source : dict
        The file's JSON, as read.
    """

    name: str
    G: TransferFunction
    F: TransferFunction
    C: TransferFunction | None
    mode: Mode
    mode_source: str
    shaper: str
    shaper_params: Mapping[str, Any]
    architecture: str
    controller: str
    ms: float
    horizon: float
    source: Mapping[str, Any] = field(default_factory=dict)
    has_load: bool = False


def load_plant(path: str | Path) -> PlantSpec:
    """Read and check a plant file (JSON, see the module's docstring).

    Raises
    ------
    ValueError
        Not JSON, not an object, an unknown key, or a value out of range (the message names it).

    Examples
    --------
    >>> import json, tempfile, os
    >>> fd, p = tempfile.mkstemp(suffix=".json"); os.close(fd)
    >>> _ = open(p, "w").write(json.dumps({"plant": {"num": [1], "den": [1, 0.2, 4, 0]}}))
    >>> spec = load_plant(p)
    >>> round(spec.mode.omega, 6), round(spec.mode.zeta, 6), spec.shaper, spec.controller
    (2.0, 0.05, 'zvd', 'pi')
    """
    text = v.path_text(path, "plant file")
    try:
        with open(text, encoding="utf-8") as fh:
            data = json.load(fh)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{text}: not a plant file (JSON): {exc.msg} at line {exc.lineno}") from None
    except UnicodeDecodeError:
        raise ValueError(f"{text}: not a plant file (JSON): not UTF-8 text") from None
    except OSError as exc:
        raise ValueError(f"cannot read {text!r}: {exc.strerror or exc}") from None
    if not isinstance(data, dict):
        raise ValueError(f"{text}: a plant file must hold a JSON object, got {type(data).__name__}")
    return plant_spec(data, Path(text).stem)


def plant_spec(data: Any, default_name: str = "plant") -> PlantSpec:
    """Check a plant description (the parsed JSON object) and return the :class:`PlantSpec`."""
    if not isinstance(data, dict):
        raise TypeError(f"data must be a plant description (a dict, as a plant file's JSON object), "
                        f"got {type(data).__name__}")
    unknown = sorted(set(data) - set(KEYS))
    if unknown:
        raise ValueError(f"unknown key(s) in the plant file: {', '.join(unknown)} (known: {', '.join(KEYS)})")
    if "plant" not in data:
        raise ValueError("the plant file needs 'plant': {\"num\": [...], \"den\": [...]}")
    name = data.get("name", default_name)
    if not isinstance(name, str):
        raise ValueError(f"name must be a string, got {name!r}")
    G = _transfer(data["plant"], "plant", allow_delay=True)
    has_load = data.get("load") is not None
    F = _transfer(data["load"], "load") if has_load else TransferFunction.constant(1.0)
    C = _transfer(data["controller"], "controller") if data.get("controller") is not None else None
    mode, mode_source = _mode(data.get("mode"), data["load"] if has_load else None, data["plant"])
    kind, params = _shaper(data.get("shaper", "zvd"))
    arch = v.choice(data.get("architecture", "control_action"), "architecture", ARCHITECTURES)
    tune = data.get("tune", {})
    if not isinstance(tune, dict) or set(tune) - {"controller", "ms"}:
        raise ValueError(f"tune must be an object with 'controller' (pd or pi) and 'ms', got {tune!r}")
    controller = v.choice(tune.get("controller", "pi"), "tune.controller", ("pd", "pi"))
    ms = v.real_in_range(tune.get("ms", 1.4), "tune.ms", 1.0, 10.0, lo_open=True)
    period = 2.0 * math.pi / mode.omega
    horizon = data.get("horizon")
    horizon = HORIZON_PERIODS * period if horizon is None else v.positive(horizon, "horizon")
    if horizon / (period / 50.0) > MAX_SAMPLES:
        raise ValueError(f"horizon must be at most {MAX_SAMPLES / 50.0:g} periods of the mode "
                         f"({MAX_SAMPLES * period / 50.0:.4g} s), got {horizon:g} s")
    return PlantSpec(name, G, F, C, mode, mode_source, kind, params, arch, controller, ms, float(horizon),
                     dict(data), has_load)


def _coefficients(value: Any, name: str) -> list[float]:
    arr = v.strict_real_array(value, name)
    if arr.ndim != 1 or arr.size == 0:
        raise ValueError(f"{name} must be a non-empty list of numbers (descending powers of s), got {value!r}")
    if not any(arr):
        raise ValueError(f"{name} must not be all zeros, got {value!r}")
    return [float(x) for x in arr]


def _transfer(value: Any, name: str, allow_delay: bool = False) -> TransferFunction:
    keys = {"num", "den"} | ({"delay"} if allow_delay else set())
    if not isinstance(value, dict) or not {"num", "den"} <= set(value) or set(value) - keys:
        raise ValueError(f"{name} must be an object with 'num' and 'den'{' (and delay)' if allow_delay else ''}, "
                         f"got {value!r}")
    num = _coefficients(value["num"], f"{name}.num")
    den = _coefficients(value["den"], f"{name}.den")
    delay = v.nonnegative(value.get("delay", 0.0), f"{name}.delay", " [s]")
    while len(num) > 1 and num[0] == 0.0:
        num = num[1:]
    while len(den) > 1 and den[0] == 0.0:
        den = den[1:]
    if len(num) > len(den):
        raise ValueError(f"{name} must be proper (numerator degree <= denominator degree), got degrees "
                         f"{len(num) - 1} > {len(den) - 1}")
    return TransferFunction.from_poly(num, den, delay)


def _mode(value: Any, load: Any, plant: Any) -> tuple[Mode, str]:
    if value is not None:
        if not isinstance(value, dict) or "zeta" not in value or len({"freq_hz", "omega"} & set(value)) != 1 \
                or set(value) - {"freq_hz", "omega", "zeta"}:
            raise ValueError(f"mode must be an object with 'freq_hz' or 'omega', and 'zeta', got {value!r}")
        if "freq_hz" in value:
            return Mode.from_hz(value["freq_hz"], value["zeta"]), "the file"
        return Mode(value["omega"], value["zeta"]), "the file"
    for blocks, what in ((load, "load"), (plant, "plant")):
        if blocks is None:
            continue
        modes = modes_of((blocks["num"], blocks["den"]), what)
        if modes:
            return modes[0], f"the {what}'s least damped poles"
    raise ValueError("no lightly damped mode in the plant or the load (no stable complex pole pair): "
                     "give 'mode': {\"freq_hz\": ..., \"zeta\": ...}")


def _shaper(value: Any) -> tuple[str, dict[str, Any]]:
    if isinstance(value, str):
        value = {"kind": value}
    if not isinstance(value, dict) or "kind" not in value:
        raise ValueError(f"shaper must be a kind (e.g. \"zvd\") or an object with 'kind', got {value!r}")
    kind = v.choice(value["kind"], "shaper.kind", tuple(KINDS))
    return kind, {k: val for k, val in value.items() if k != "kind"}

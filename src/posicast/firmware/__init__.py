"""Printer firmware: the shapers each firmware runs, how it scores them, and its configuration lines.

>>> from posicast.firmware import FIRMWARES
>>> sorted(FIRMWARES)
['klipper', 'marlin', 'prusa', 'reprapfirmware']
"""

from .base import Firmware, Setting, ShaperType, smoothing_offsets, vibration_grid
from .klipper import Klipper
from .others import MarlinFT, Prusa, RepRapFirmware

__all__ = ["Firmware", "Setting", "ShaperType", "Klipper", "RepRapFirmware", "MarlinFT", "Prusa", "FIRMWARES",
           "smoothing_offsets", "vibration_grid"]

#: The firmwares posicast writes configuration for, by name.
FIRMWARES: dict[str, type[Firmware]] = {"klipper": Klipper, "reprapfirmware": RepRapFirmware, "marlin": MarlinFT,
                                        "prusa": Prusa}

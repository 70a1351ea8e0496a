"""Physical constants and the array type aliases every room shares (SI inside msk)."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["G0", "Array", "BoolArray", "IntArray"]

#: standard gravity (m/s²): body weight = mass × G0 (ISO 80000-3; the kilogram-force's definition)
G0 = 9.80665

#: a float64 array (time on axis 0 where it is a time series)
Array = NDArray[np.float64]
#: an integer index array
IntArray = NDArray[np.intp]
#: a boolean mask
BoolArray = NDArray[np.bool_]

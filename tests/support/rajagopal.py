"""The Rajagopal walk of the real-data strength tests: msk's own loader and mapping
(:mod:`studies.seed003`: muscle → EMG electrode, synergist groups, model, ID and EMG
tables, muscle geometry along the recorded coordinates)."""

from studies.seed003 import COORDS, EMG_MAP, GROUPS, RATE_HZ, rajagopal_walk

__all__ = ["COORDS", "EMG_MAP", "GROUPS", "RATE_HZ", "rajagopal_walk"]

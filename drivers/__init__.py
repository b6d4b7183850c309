"""Sensor drivers: bytes in, typed and time-stamped frames out, in the body frame (FRD).

The drivers know protocols and ports and nothing about tracking.
"""

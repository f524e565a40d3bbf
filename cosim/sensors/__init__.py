"""Real sensor data: recorded IMU logs, their replay, and the characterisation of a sensor.

=================  ==========================================================================
module             what it does
=================  ==========================================================================
``logs``           read CSV, Parquet and HDF5 IMU logs in chunks, with unit-labelled columns
                   and checked timestamps (:class:`~cosim.sensors.logs.ImuLog`)
``replay``         the ``ImuLogReplay`` block: fills the ``imu`` role from a log
``fmu``            pack a log and the replay block into an FMU (the log in its resources)
``characterize``   Allan deviation per axis, fitted noise terms, grade presets
=================  ==========================================================================

This package imports nothing at import time: the replay block is also shipped inside an
FMU with only ``numpy`` and ``models`` beside it (:mod:`cosim.sensors.fmu`).
"""

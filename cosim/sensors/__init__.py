"""Real sensor data: recorded IMU logs, their replay, and the characterisation of a sensor.

=================  ==========================================================================
module             what it does
=================  ==========================================================================
``logs``           IMU and master-INS logs read in chunks, with unit-labelled columns and
                   checked timestamps (:class:`~cosim.sensors.logs.ImuLog`), ``write_csv``
``formats``        the CSV, Parquet and HDF5 readers underneath, and the log errors
``replay``         the ``ImuLogReplay`` block: fills the ``imu`` role from a log
``master_replay``  the ``MasterInsLogReplay`` block: fills the ``master_ins`` role
``fmu``            pack a log and the replay block into an FMU (the log in its resources)
``characterize``   Allan deviation per axis, fitted noise terms, grade presets
``report``         ``ins-cosim characterize``: the files it writes, the parameter block
``placement``      ``ins-cosim place``: a real run's percentile in a campaign
``demo``           a simulated static log standing in for a lab recording
=================  ==========================================================================

This package imports nothing at import time: the replay block is also shipped inside an
FMU with only ``numpy`` and ``models`` beside it (:mod:`cosim.sensors.fmu`).
"""

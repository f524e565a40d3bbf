"""Interoperability: role specs, check-fmu, SSP, libcosim, C builds, FMU packaging, references."""

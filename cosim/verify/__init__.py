"""Verification: requirements, the campaign engine, reports and plots."""

"""Hydraulic circuits described from components and compiled by code generation (issue 18)."""

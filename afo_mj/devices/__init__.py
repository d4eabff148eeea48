"""Ankle orthoses assembled from the hydraulic component library."""

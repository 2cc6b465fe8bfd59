"""Synthetic scenes with known truth: sensors, terrain, points and rendered images."""

"""Planners: cells, navigation plans and coverage models, from a map alone (no robot)."""

"""Procedural scenes (built from primitives, seeded, offline). `room`: the flight-test room."""

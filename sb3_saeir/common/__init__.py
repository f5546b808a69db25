"""Shared machinery of sb3_saeir."""

"""Pymunk's home: its adapter."""

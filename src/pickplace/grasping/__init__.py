"""Grasps: tcp targets, their joint configurations, force closure of the contacts, and the hold test."""

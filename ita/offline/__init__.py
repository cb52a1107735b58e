"""Offline components: preparation of a part for inspection (`ita prepare`)."""

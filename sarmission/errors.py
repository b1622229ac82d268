"""Errors that reach the user as one clear line (the CLI prints them without a traceback)."""


class SarmissionError(Exception):
    """An expected failure caused by the user's input or environment, with a readable message."""

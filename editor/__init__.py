"""FAP Studio: MPEG-4 facial animation of a single photo."""

__version__ = "0.1.0"

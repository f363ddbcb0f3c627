"""Commands of this concept (registered on the shared typer app)."""

from .app import app  # noqa: F401

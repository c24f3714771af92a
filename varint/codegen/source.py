"""The buffer every emitter writes Python source into: lines with an
indentation level."""

from __future__ import annotations

from contextlib import contextmanager

__all__ = ["Source"]


class Source:
    """Lines of Python source; ``src("a = 1", "b = 2")`` appends lines at the
    current indentation, ``with src.block("if a:"):`` indents what follows."""

    def __init__(self):
        self.lines = []
        self.level = 0

    def __call__(self, *lines):
        for line in lines:
            self.lines.append("    " * self.level + line if line else "")

    @contextmanager
    def block(self, header=None):
        """Indent the lines written inside, after ``header`` if given."""
        if header is not None:
            self(header)
        self.level += 1
        try:
            yield
        finally:
            self.level -= 1

    def text(self):
        return "\n".join(self.lines) + "\n"

"""The documentation's pages run as written: every ``>>>`` example of
docs/*.rst and docs/user_guide/*.rst, with its output (the site's gallery
runs when the site is built; see docs/contributing.rst)."""

import doctest
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"
PAGES = sorted(p for pattern in ("*.rst", "user_guide/*.rst") for p in DOCS.glob(pattern))


def test_the_pages_are_found():
    assert DOCS / "getting_started.rst" in PAGES and DOCS / "user_guide/maps.rst" in PAGES


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(DOCS)))
def test_page_examples(page):
    result = doctest.testfile(str(page), module_relative=False, report=True, verbose=False,
                              optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0, f"{result.failed} example(s) of {page.name} failed (see above)"


# -- every code block stands alone ------------------------------------------------------

import ast  # noqa: E402
import builtins  # noqa: E402
import re  # noqa: E402
import textwrap  # noqa: E402

README = DOCS.parent / "README.md"


def _code_blocks():
    """(where, code) of every Python code block of the pages and README."""
    out = []
    for page in PAGES:
        text = page.read_text()
        for m in re.finditer(r"( *)\.\. code-block:: python\n\n((?:(?:\1   .*)?\n)+)", text):
            code = textwrap.dedent(m.group(2))
            out.append((f"{page.relative_to(DOCS)}:{text[:m.start()].count(chr(10)) + 1}",
                        code))
    text = README.read_text()
    for m in re.finditer(r"```python\n(.*?)```", text, re.S):
        code = "\n".join(re.sub(r"^(>>>|\.\.\.) ?", "", line)
                         for line in m.group(1).splitlines())
        out.append((f"README.md:{text[:m.start()].count(chr(10)) + 1}", code))
    return out


def _undefined(code):
    """Names a block loads without defining or importing them (a block
    that leans on an earlier one fails when pasted alone)."""
    tree = ast.parse(code)
    defined = set(dir(builtins))
    for node in ast.walk(tree):
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            defined |= {(a.asname or a.name).split(".")[0] for a in node.names}
        elif isinstance(node, ast.Name) and isinstance(node.ctx, (ast.Store, ast.Del)):
            defined.add(node.id)
        elif isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            defined.add(node.name)
            defined |= {a.arg for a in node.args.args} if hasattr(node, "args") else set()
        elif isinstance(node, ast.Lambda):
            defined |= {a.arg for a in node.args.args}
        elif isinstance(node, ast.arg):
            defined.add(node.arg)
    loaded = {n.id for n in ast.walk(tree) if isinstance(n, ast.Name)
              and isinstance(n.ctx, ast.Load)}
    return sorted(loaded - defined)


BLOCKS = _code_blocks()


def test_code_blocks_are_found():
    assert len(BLOCKS) >= 15


@pytest.mark.parametrize("where, code", BLOCKS, ids=[w for w, _ in BLOCKS])
def test_every_code_block_stands_alone(where, code):
    """Every ``.. code-block:: python`` of the pages and every README block
    parses and defines or imports every name it uses: pasted alone into a
    fresh interpreter, it runs (README's blocks are also run, each alone,
    by tests/test_readme.py; the pages' doctests by the test above)."""
    missing = _undefined(code)
    assert not missing, f"{where} uses {', '.join(missing)} without defining it"

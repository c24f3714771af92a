"""A generated module's name hashes every file its source is made of.

numba's cache and varint's signed code cache load a module by name: a file
that writes part of a generated source, if left out of the generator's
hash, would let a changed varint load a stale module (signed by the user's
own secret, so trusted) instead of writing the new one. Checked from the
imports of the generating layers themselves, so a new dependency that is
not hashed fails here.
"""

import ast
from pathlib import Path

import varint
from varint.codegen import lh, stepper

PACKAGE = Path(varint.__file__).resolve().parent

#: Modules a generating layer imports only to name, store or sign what it
#: writes (never to write source): the cache directory and its signing, the
#: canonical JSON of keys, the naming of closed-over values.
NAMING_ONLY = {"cachedir.py", "codecache.py", "files.py", "kernels/closures.py"}


def _imported_files(path):
    """The varint files ``path`` imports (relative imports, at any depth
    of the module, including names imported from a package)."""
    here = path.parent
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if not isinstance(node, ast.ImportFrom) or node.level == 0:
            continue
        base = here
        for _ in range(node.level - 1):
            base = base.parent
        target = base.joinpath(*node.module.split(".")) if node.module else base
        for alias in node.names:
            for candidate in (target / alias.name / "__init__.py",
                              target / f"{alias.name}.py",
                              target.with_suffix(".py"), target / "__init__.py"):
                if candidate.is_file():
                    found.add(candidate.resolve())
                    break
    return found


def _relative(paths):
    return {p.resolve().relative_to(PACKAGE).as_posix() for p in paths}


def _closure(roots, within):
    """The files reachable by imports from ``roots``, following only files
    under ``within`` (the generating layer); every reached file is kept."""
    seen, todo = set(), [p.resolve() for p in roots]
    while todo:
        path = todo.pop()
        if path in seen:
            continue
        seen.add(path)
        todo.extend(p for p in _imported_files(path) if within in p.parents)
    return seen


def _made_of(emitter):
    """The files the emitter and the layer's modules it imports reach."""
    reached = _closure([PACKAGE / "codegen" / emitter], PACKAGE / "codegen")
    imported = set(reached)
    for path in reached:
        imported |= _imported_files(path)
    return _relative(imported)


def test_the_stepper_generator_hashes_every_file_its_emitter_imports():
    missing = _made_of("stepper.py") - _relative(stepper.generator_sources()) - NAMING_ONLY
    assert not missing, f"a TM stepper's source reads these, its name does not hash them: {missing}"


def test_the_lh_generator_hashes_every_file_its_emitter_imports():
    missing = _made_of("lh.py") - _relative(lh.generator_sources()) - NAMING_ONLY
    assert not missing, f"an LH module's source reads these, its name does not hash them: {missing}"


def test_the_import_scan_sees_the_printer_behind_the_printer():
    # The scan itself can fail: the expression printer is two imports away
    # from either emitter (… -> codegen.printer -> models.symbolic), which
    # the TM stepper's name did not hash before.
    assert "models/symbolic.py" in _made_of("stepper.py")
    assert "models/symbolic.py" in _made_of("lh.py")

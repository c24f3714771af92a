"""Pages generated from varint's registries, so that what is registered is
what is documented.

Directives (each takes no argument):

``.. varint-indicators::``
    One section per entry of :data:`varint.INDICATORS`: its summary, how
    its vectors are renormalised, its options with their defaults and docs,
    its map value, its laws and its references. A newly registered
    indicator appears here with no edit to the documentation.
``.. varint-methods::``
    One section per entry of :data:`varint.METHODS`: the propagator's
    summary, and its options with the descriptions of its docstring's
    Parameters section.
``.. varint-schemes::``
    A table of :data:`varint.SCHEMES`: order, force evaluations per step,
    corrector, reference.
``.. varint-cli::``
    ``varint --help`` and the help of every sub-command, as the parser
    prints them.

Role:

``:q:`NAME```
    A measured figure, rendered when the site is built from the results
    stored under ``studies/results/`` by the quote ``NAME`` of
    ``studies/quotes.py`` (no measured number is typed into a page).
"""

from __future__ import annotations

import contextlib
import importlib
import inspect
import io
import os
import re

from docutils import nodes
from docutils.statemachine import StringList
from sphinx.util.docutils import SphinxDirective
from sphinx.util.nodes import nested_parse_with_titles

# Arguments of every propagator's constructor; not options a user passes.
_PROPAGATOR_ARGUMENTS = {"model", "tau", "renorm", "accumulator"}


def _inline(text):
    """Registry text (plain Unicode) made safe for reStructuredText: the
    characters that start markup are escaped."""
    return re.sub(r"([*`|_\\])", r"\\\1", str(text))


def _first_paragraph(doc):
    doc = inspect.cleandoc(doc or "")
    return " ".join(doc.split("\n\n")[0].split())


def _table(header, rows, widths=None):
    lines = [".. list-table::", "   :header-rows: 1"]
    if widths:
        lines.append(f"   :widths: {' '.join(map(str, widths))}")
    lines.append("")
    for row in [header] + rows:
        first = True
        for cell in row:
            lines.append(("   * - " if first else "     - ") + (cell or " "))
            first = False
    return lines + [""]


class _Generated(SphinxDirective):
    has_content = False

    def lines(self):
        raise NotImplementedError

    def run(self):
        node = nodes.section() if self.sections else nodes.container()
        node.document = self.state.document
        content = StringList(self.lines(), source="varint registry")
        if self.sections:
            nested_parse_with_titles(self.state, content, node)
        else:
            self.state.nested_parse(content, self.content_offset, node)
        return node.children

    sections = True


@contextlib.contextmanager
def _environ(**values):
    saved = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _default(value):
    return "derived (see the description)" if value is None else f"``{value!r}``"


def _threshold(indicator):
    t = indicator.threshold
    if t is None:
        return "none (every orbit runs to t_end)"
    if callable(t):
        return "depends on the model and the options (see the description)"
    return f"{t:g}, {'below' if indicator.below else 'above'} which an orbit is decided"


class IndicatorsDirective(_Generated):
    """Every registered indicator, from :data:`varint.INDICATORS`."""

    def lines(self):
        from varint import INDICATORS
        from varint.indicators import base

        aliases = {}
        for alias, (target, fixed) in getattr(base, "_ALIASES", {}).items():
            aliases.setdefault(target, []).append((alias, fixed))
        # The built-in ones in the order a reader meets them, then any other
        # in the order it was registered.
        first = ("lyapunov", "gali", "sali", "megno", "fli", "ofli", "local_exponents",
                 "integrate")
        names = [n for n in first if n in INDICATORS] + [n for n in INDICATORS if n not in first]
        out = []
        for name in names:
            ind = INDICATORS[name]
            title = name
            out += [f".. _indicator-{name}:", "", title, "-" * len(title), "",
                    _inline(ind.summary[:1].upper() + ind.summary[1:]) + ".", ""]
            result = ind.result
            facts = [
                ("result", f":class:`~{result.__module__}.{result.__qualname__}`"
                 if result.__module__.startswith("varint.results") or name == "local_exponents"
                 else f"``{result.__qualname__}``"),
                ("deviation vectors", {"qr": "re-orthonormalised (QR) every τ",
                                       "normalize": "normalised to unit length every τ",
                                       "none": "never renormalised"}[ind.renorm.name.lower()]),
                ("given vectors must be", {None: "anything (or none)",
                                           "orthonormal": "orthonormal columns",
                                           "unit": "independent columns (normalised before use)"}
                 [ind.require]),
                ("accumulated every step", "yes (the same compiled code in every method)"
                 if ind.accumulator is not None else "no"),
                ("chaos map value", "yes" if ind.scalar is not None else "no"),
            ]
            if ind.scalar is not None:
                facts.append(("map early stopping", _threshold(ind)))
            if name in aliases:
                facts.append(("shorthands", ", ".join(
                    f"``{a}``" + (f" (= {', '.join(f'{k}={v!r}' for k, v in fixed.items())})"
                                  if fixed else "") for a, fixed in aliases[name])))
            if name == "gali":
                facts.append(("shorthands", "``gali_k`` (e.g. ``gali_3``: GALI with k = 3)"))
            for label, text in facts:
                out += [f":{label}: {text}"]
            out.append("")
            if ind.options:
                out += ["**Options** (keyword arguments of :func:`varint.run` and "
                        ":func:`varint.chaos_map`):", ""]
                out += _table(["option", "default", "meaning"],
                              [[f"``{k}``", _default(o.default), _inline(o.doc)]
                               for k, o in ind.options.items()], widths=[2, 2, 6])
            if ind.laws:
                out += ["**Laws.** " + _inline(ind.laws[:1].upper() + ind.laws[1:]) + ".", ""]
            if ind.references:
                out += ["**References.**", ""]
                out += [f"* {_inline(r)}" for r in ind.references] + [""]
        return out


def _parameters(cls):
    """name -> (type, description) from the class docstring's Parameters."""
    from numpydoc.docscrape import NumpyDocString

    with contextlib.suppress(Exception):
        doc = NumpyDocString(inspect.getdoc(cls) or "")
        out = {}
        for p in doc["Parameters"]:
            for name in (n.strip() for n in p.name.split(",")):
                out[name] = (p.type, " ".join(p.desc))
        return out
    return {}


class MethodsDirective(_Generated):
    """Every registered method, from :data:`varint.METHODS`."""

    def lines(self):
        from varint import METHODS
        from varint.methods import propagator_class

        out = []
        for name, target in METHODS.items():
            cls = propagator_class(name)
            title = f"``method=\"{name}\"``"
            path = f"{cls.__module__}.{cls.__qualname__}"
            out += [f".. _method-{name}:", "", title, "-" * len(title), "",
                    _first_paragraph(cls.__doc__), "",
                    f"Implemented by :class:`~{path}` (registered as ``\"{target}\"``).", ""]
            options = cls.OPTIONS
            defaults = options if isinstance(options, dict) else dict.fromkeys(options)
            params = _parameters(cls)
            rows = []
            for opt, default in defaults.items():
                kind, desc = params.get(opt, ("", ""))
                stated = re.search(r"default[\s=]+(.+)$", kind or "")
                shown = (f"``{default!r}``" if default is not None
                         else f"``{stated.group(1)}``" if stated else "—")
                rows.append([f"``{opt}``", shown, _escape_bars(desc) or "—"])
            if rows:
                out += ["**Options:**", ""]
                out += _table(["option", "default", "meaning"], rows, widths=[2, 2, 7])
            else:
                out += ["No options.", ""]
        return out


class SchemesDirective(_Generated):
    """The table of registered two-part splitting schemes (H = A + B)."""

    sections = False

    def lines(self):
        from varint.schemes import registered

        rows = [[f"``{s.name}``", str(s.order), s.nominal_order or "—",
                 str(s.force_evaluations), "yes" if s.corrector is not None else "no",
                 _inline(s.reference) or "—"] for s in registered(2)]
        return _table(["name", "order", "published order", "force evaluations / step",
                       "corrector", "reference"], rows, widths=[2, 1, 2, 2, 1, 6])


class ModelsDirective(_Generated):
    """The table of registered built-in models
    (:data:`varint.models.registry.MODELS`)."""

    sections = False

    def lines(self):
        from varint.models.registry import MODELS

        kinds = {"flow": "flow", "map": "symplectic map", "lattice": "lattice"}
        rows = [[f"``{e.name}``", kinds[e.kind], _inline(e.summary),
                 ", ".join(f"``{p.name}`` = {p.default:g}: {_inline(p.doc)}"
                           for p in e.parameters) or "—",
                 ", ".join(e.coordinates) if e.coordinates else "—"]
                for e in MODELS.values()]
        return _table(["name", "kind", "what", "parameters (default)", "coordinates"], rows,
                      widths=[2, 2, 6, 5, 2])


class CLIDirective(_Generated):
    """``varint --help`` and every sub-command's help."""

    sections = True

    def lines(self):
        from varint.cli import build_parser

        # argparse wraps at the terminal's width: fix it for the page.
        with _environ(COLUMNS="88"):
            parser = build_parser()
            text = parser.format_help()
        # The sub-commands, as the help lists them under its COMMAND
        # positional: one per line, indented by four spaces.
        listing = text[text.index("\n  COMMAND"):]
        commands = re.findall(r"^    ([a-z][\w-]*)\s", listing, re.M)
        if not commands:
            raise RuntimeError("no sub-command found in the help of varint.cli.build_parser()")
        out = []
        for name in ["varint"] + commands:
            title = f"``{name if name == 'varint' else 'varint ' + name}``"
            buf = io.StringIO()
            with _environ(COLUMNS="88"), contextlib.redirect_stdout(buf), \
                    contextlib.suppress(SystemExit):
                parser.parse_args(([] if name == "varint" else [name]) + ["--help"])
            out += [title, "-" * len(title), "", ".. code-block:: text", ""]
            out += ["   " + line for line in buf.getvalue().rstrip().splitlines()] + [""]
        return out


_LITERAL = re.compile(r"(``.*?``|:[\w:.-]+:`.*?`|`[^`]*`_?)")


def _escape_bars(line):
    """``|`` outside inline literals and roles, escaped."""
    parts = _LITERAL.split(line)
    return "".join(p if i % 2 else p.replace("|", "\\|") for i, p in enumerate(parts))


def escape_plain_math(app, what, name, obj, options, lines):
    """Docstrings write norms and absolute values as plain Unicode, |x|,
    ‖w‖ (they are read in terminals first); in reStructuredText ``|x|`` is
    a substitution. Escape the bars of prose, leaving literal blocks,
    directive bodies (``.. math::``), doctests and inline literals alone."""
    block_indent = None      # indentation of the literal block we are in
    opens_block = False      # the previous paragraph ended with "::"
    doctest = False
    for i, line in enumerate(lines):
        stripped = line.lstrip()
        indent = len(line) - len(stripped)
        if not stripped:
            doctest = False
            continue
        if block_indent is not None and indent >= block_indent:
            continue
        block_indent = None
        if opens_block:
            opens_block = False
            block_indent = indent
            continue
        if stripped.startswith(">>>"):
            doctest = True
        table_row = stripped.startswith("|") and stripped.endswith("|") and stripped.count("|") > 2
        if doctest or table_row or stripped.startswith(("+-", "==")):
            continue
        lines[i] = _escape_bars(line)
        if stripped.endswith("::"):
            opens_block = True
            block_indent = None
    # A citation such as [LR01]_ defined in the module's docstring has no
    # target on an object's page: keep it as text.
    defined = set(re.findall(r"^\s*\.\. \[(\w+)\]", "\n".join(lines), re.M))
    for i, line in enumerate(lines):
        lines[i] = re.sub(r"\[(\w+)\]_", lambda m: m.group(0) if m.group(1) in defined
                          else f"[{m.group(1)}]", line)
    return lines


def quote_role(name, rawtext, text, lineno, inliner, options=None, content=()):
    """``:q:`NAME```: the text of the quote NAME (``studies/quotes.py``) from
    the stored results; an unknown quote or a missing result is an error."""
    from studies.quotes import render

    try:
        return [nodes.Text(render(text.strip()))], []
    except (KeyError, LookupError, FileNotFoundError) as exc:
        msg = inliner.reporter.error(f"quote {text!r}: {exc}", line=lineno)
        return [inliner.problematic(rawtext, rawtext, msg)], [msg]


def setup(app):
    app.add_role("q", quote_role)
    # Before numpydoc (priority 500) turns the sections into markup.
    app.connect("autodoc-process-docstring", escape_plain_math, priority=400)
    app.add_directive("varint-indicators", IndicatorsDirective)
    app.add_directive("varint-methods", MethodsDirective)
    app.add_directive("varint-schemes", SchemesDirective)
    app.add_directive("varint-cli", CLIDirective)
    app.add_directive("varint-models", ModelsDirective)
    return {"parallel_read_safe": True, "parallel_write_safe": True, "version": "1"}


# Import here so that a broken registry fails the build at once, with the
# error, rather than on the page that uses it.
importlib.import_module("varint")

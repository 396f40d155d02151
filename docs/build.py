"""Build the HTML documentation, with every Sphinx warning an error.

    python docs/build.py [OUT]     # default OUT: docs/_build/html

The hand-written pages (``conf.py``, the ``.rst`` and ``.md`` pages, ``_static/``) are copied into
a temporary source folder beside four generated ones:

- ``api.rst``: the public names (``pbvs_pin.__all__``), each documented where it is defined
  (autodoc + napoleon, Google style);
- ``internals.rst``: every other module of the package and its members;
- ``scenario_keys.rst``: every scenario key, generated from the typed sections of
  :mod:`pbvs_pin.control.tables` and :mod:`pbvs_pin.sim.sections`
  (:func:`~pbvs_pin.toml_keys.keys_of`) and the obstacle classes;
- ``sweep_keys.rst``: every key of a sweep spec, from :mod:`pbvs_pin.study.sweep.spec`.

Nothing is fetched: the build works offline.
"""

from __future__ import annotations

import inspect
import pkgutil
import re
import shutil
import sys
import tempfile
from dataclasses import MISSING, fields
from pathlib import Path
from typing import Any

import pbvs_pin
from pbvs_pin.sim.scenario import OBSTACLE_KINDS, Scenario
from pbvs_pin.sim.sections import SECTIONS
from pbvs_pin.study.sweep.spec import SWEEP_DEFAULTS, SWEEP_KEY_DOCS, SWEEP_TABLE_DOCS
from pbvs_pin.toml_keys import Sign, keys_of

DOCS = Path(__file__).resolve().parent
NOT_PAGES = ("_build", "build.py", "gallery.py", "__pycache__")
"""What of ``docs/`` is not copied into the source folder."""


def heading(title: str, underline: str) -> str:
    """An RST section title."""
    return f"{title}\n{underline * len(title)}\n\n"


def literal(value: Any) -> str:
    """A value as inline TOML-ish code (empty cell for "absent")."""
    if value is None:
        return "absent"
    if isinstance(value, bool):
        return f"``{str(value).lower()}``"
    if isinstance(value, str):
        return f'``"{value}"``'
    if isinstance(value, tuple):
        value = list(value)
    return f"``{value}``"


def table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> str:
    """An RST list-table."""
    lines = [".. list-table::", "   :header-rows: 1", "   :widths: auto", ""]
    for row in [header, *rows]:
        lines.append(f"   * - {row[0]}")
        lines.extend(f"     - {cell}" for cell in row[1:])
    return "\n".join(lines) + "\n\n"


def _public() -> dict[str, str]:
    """``name -> "module.name"``: each public name and where it is defined."""
    public = {}
    for name in pbvs_pin.__all__:
        obj = getattr(pbvs_pin, name)
        module = getattr(obj, "__module__", None)
        if inspect.isclass(obj) or inspect.isfunction(obj):
            public[name] = f"{module}.{obj.__qualname__}"
    return public


def api_page() -> str:
    """``api.rst``: the public names of ``pbvs_pin.__all__``, each where it is defined."""
    text = heading("API reference", "=")
    text += (
        "The names ``import pbvs_pin`` exports (``pbvs_pin.__all__``), in that order. Everything "
        "else is internal: :doc:`internals`.\n\n"
        ".. automodule:: pbvs_pin\n   :no-members:\n\n"
    )
    constants = [n for n in pbvs_pin.__all__ if n not in _public()]
    for name, target in _public().items():
        obj = getattr(pbvs_pin, name)
        directive = "autoclass" if inspect.isclass(obj) else "autofunction"
        text += heading(name, "-") + f".. {directive}:: {target}\n\n"
    if constants:
        text += heading("Constants", "-")
        for name in constants:
            text += f"- ``pbvs_pin.{name}`` = ``{getattr(pbvs_pin, name)!r}``\n"
        text += "\n"
    return text


def internals_page() -> str:
    """``internals.rst``: every module of the package, the public names left out."""
    public = set(_public().values())
    modules = pkgutil.walk_packages(pbvs_pin.__path__, "pbvs_pin.")
    text = heading("Internals", "=")
    text += (
        "Every module of the package, generated from its docstrings. These names may change "
        "between versions; the stable ones are on :doc:`api`.\n\n"
    )
    for name in sorted(info.name for info in modules):
        text += heading(name, "-") + f".. automodule:: {name}\n"
        exclude = sorted(p.rsplit(".", 1)[1] for p in public if p.rsplit(".", 1)[0] == name)
        if exclude:
            text += "   :exclude-members: " + ", ".join(exclude) + "\n"
        text += "\n"
    return text


def constraint(spec: Any) -> str:
    """Type and check of a :func:`~pbvs_pin.toml_keys.key` field, in words."""
    meta, default = spec.metadata, spec.default
    if meta["choices"]:
        words = "one of " + ", ".join(f"``{c}``" for c in meta["choices"])
    elif meta.get("names"):
        words = "array of names or absent"
    elif meta["optional"] is not None:
        words = f"{meta['optional'].__name__} or absent"
    elif default is None or isinstance(default, tuple):
        words = "array" + (f" of {meta['length']}" if meta["length"] else "")
        words += " or absent" if default is None else ""
    else:
        words = type(default).__name__
    if meta["sign"] is not Sign.ANY:
        words += f", {meta['sign'].value}"
    return words


def section_rows(cls: type) -> list[tuple[str, ...]]:
    """One row per key of a section: key, default, type and check, meaning."""
    return [
        (f"``{spec.name}``", literal(spec.default), constraint(spec), spec.metadata["doc"])
        for spec in keys_of(cls)
    ]


def attribute_docs(cls: type) -> dict[str, str]:
    """``name -> text`` from a Google-style ``Attributes:`` section of a class docstring."""
    found = {}
    in_section = False
    for line in (inspect.getdoc(cls) or "").splitlines():
        if line.strip() == "Attributes:":
            in_section = True
        elif in_section and (match := re.match(r"\s+(\w+):\s*(.*)", line)):
            found[match.group(1)] = match.group(2)
    return found


def scenario_page() -> str:
    """``scenario_keys.rst``: every table and key of a scenario file."""
    header = ("key", "default", "type", "meaning")
    text = heading("Scenario keys", "=")
    text += (
        "Every key a scenario file may hold, generated from the typed sections of "
        ":mod:`pbvs_pin.control.tables` and :mod:`pbvs_pin.sim.sections`. An absent key takes its default; an unknown key, a "
        "wrong type, a wrong array length or a value of the wrong sign is an error naming the "
        "file and the dotted field.\n\n"
    )
    text += heading("Root keys", "-") + table(header, section_rows(Scenario))
    for cls in SECTIONS:
        summary = (inspect.getdoc(cls) or "").split("\n\n")[0].replace("\n", " ")
        text += heading(f"[{cls.TABLE}]", "-") + f"{summary}\n\n"
        text += table(header, section_rows(cls))
    text += heading("[[obstacles]]", "-")
    text += "An array of tables, each with a ``kind`` and that kind's keys.\n\n"
    for kind, cls in OBSTACLE_KINDS.items():
        docs = attribute_docs(cls)
        rows = [
            (
                f"``{spec.name}``",
                "required" if spec.default is MISSING else literal(spec.default),
                spec.type if isinstance(spec.type, str) else spec.type.__name__,
                docs.get(spec.name, ""),
            )
            for spec in fields(cls)
        ]
        text += heading(f'kind = "{kind}"', "~") + table(header, rows)
    return text


def sweep_page() -> str:
    """``sweep_keys.rst``: the tables and keys of a sweep spec."""
    text = heading("Sweep keys", "=")
    text += (
        "Every key of a sweep spec (``pbvs-pin sweep SPEC``), generated from "
        ":mod:`pbvs_pin.study.sweep.spec`. Field names are dotted scenario keys "
        "(:doc:`scenario_keys`), checked when the spec is read.\n\n"
    )
    rows = [
        (
            f"``{name}``",
            "required" if name == "scenario" else literal(default),
            SWEEP_KEY_DOCS[name],
        )
        for name, default in SWEEP_DEFAULTS.items()
    ]
    text += heading("[sweep]", "-") + table(("key", "default", "meaning"), rows)
    for name, doc in SWEEP_TABLE_DOCS.items():
        text += heading(f"[{name}]", "-") + doc + "\n\n"
    return text


GENERATED = ("api.rst", "internals.rst", "scenario_keys.rst", "sweep_keys.rst")
"""The pages :func:`generate` writes from the code."""


def generate(source: Path) -> None:
    """Write the hand-written and the generated pages into ``source``."""
    shutil.copytree(DOCS, source, ignore=shutil.ignore_patterns(*NOT_PAGES), dirs_exist_ok=True)
    pages = (api_page, internals_page, scenario_page, sweep_page)
    for name, page in zip(GENERATED, pages, strict=True):
        (source / name).write_text(page())


def build(out: Path) -> int:
    """Generate the pages and run Sphinx with warnings as errors; say what was done.

    Returns:
        Sphinx's exit status (0: built without a warning).
    """
    from sphinx.cmd.build import build_main

    with tempfile.TemporaryDirectory() as folder:
        source = Path(folder) / "source"
        generate(source)
        pages = len(list(source.glob("*.rst")) + list(source.glob("*.md")))
        print(f"building {pages} pages (4 generated: {', '.join(GENERATED)}) into {out}")
        status = build_main(
            ["-W", "--keep-going", "-q", "-E", "-d", str(Path(folder) / "doctrees"),
             "-b", "html", str(source), str(out)]
        )  # fmt: skip
    if status == 0:
        written = len(list(Path(out).glob("*.html")))
        print(f"documentation built: {written} HTML pages, no warning; open {out / 'index.html'}")
    else:
        print(
            f"documentation NOT built (Sphinx status {status}): every Sphinx warning is an "
            "error here; fix the warnings printed above",
            file=sys.stderr,
        )
    return status


if __name__ == "__main__":
    sys.exit(build(Path(sys.argv[1]) if len(sys.argv) > 1 else DOCS / "_build" / "html"))

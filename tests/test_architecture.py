"""The package's architecture, checked: the stages in the order data flows through them.

:data:`STAGES` is the one statement of foldfab's architecture.  Every module under
``foldfab/`` belongs to one stage; a module may import modules of its own stage and of
earlier stages only (at module level, inside functions and under ``TYPE_CHECKING`` alike:
all three are dependencies), and no modules import one another in a cycle.  A new module
must be given its stage here, which is the point: where it goes is a decision.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest
from helpers import ROOT

PACKAGE = ROOT / "foldfab"

STAGES: list[tuple[str, tuple[str, ...]]] = [
    ("base", ("foldfab", "foldfab.errors", "foldfab.files", "foldfab.atomic", "foldfab.xdg", "foldfab.limits")),
    ("job", ("foldfab.job",)),                        # job files: read, checked, written
    ("geometry", ("foldfab.geometry",)),              # profile, trajectory -> reflection, crease pattern
    ("design", ("foldfab.design",)),                  # job -> geometry: the one entry point
    ("formats", ("foldfab.formats",)),                # design -> FOLD, SVG, ORIPA, meshes
    ("devices", ("foldfab.devices",)),                # plotter profiles
    ("fabrication", ("foldfab.fabrication",)),        # design + device + [fabrication] -> plot plan
    ("printing", ("foldfab.printing",)),              # design -> printable template (PDF, SVG pages)
    ("programs", ("foldfab.programs", "foldfab.program", "foldfab.interpret")),  # plot plan -> program, read back
    ("fabricate", ("foldfab.fabricate",)),            # design -> program: the one entry point
    ("sim", ("foldfab.sim",)),                        # simulated plotters
    ("plotting", ("foldfab.plotting", "foldfab.urlhandler")),   # program -> a machine, resume
    ("queue", ("foldfab.queue",)),                    # jobs waiting for plotters, workers
    ("studio", ("foldfab.studio",)),                  # the browser designer
    ("cli", ("foldfab.cli", "foldfab.__main__")),     # argument parsing and printing
]

MAX_LINES = 600
LONGER: dict[str, str] = {}
"""Modules allowed over :data:`MAX_LINES`, each with the reason one concept needs more."""


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def sources() -> dict[str, str]:
    """Every module of the package: dotted name -> source text."""
    return {module_name(p): p.read_text(encoding="utf-8") for p in sorted(PACKAGE.rglob("*.py"))}


def stage_of(module: str) -> int:
    """The index in :data:`STAGES` of the stage ``module`` belongs to: the stage naming it or the
    package holding it (the longest name wins; the root package ``foldfab`` holds none)."""
    best, length = None, -1
    for index, (_, prefixes) in enumerate(STAGES):
        for prefix in prefixes:
            inside = prefix != "foldfab" and module.startswith(prefix + ".")
            if (module == prefix or inside) and len(prefix) > length:
                best, length = index, len(prefix)
    if best is None:
        raise LookupError(f"{module} belongs to no stage: add it to STAGES in {__file__}")
    return best


def imports(module: str, source: str, known: set[str]) -> set[str]:
    """The foldfab modules ``module`` imports anywhere in its text (``from foldfab.x import y``
    counts ``foldfab.x.y`` where that is a module, else ``foldfab.x``)."""
    is_package = any(name.startswith(module + ".") for name in known) or module == "foldfab"
    found = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = module.split(".") if is_package else module.split(".")[:-1]
                anchor = anchor[:len(anchor) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            for alias in node.names:
                found.add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base)
    return {name for name in found if name == "foldfab" or name.startswith("foldfab.")} - {module}


def graph(texts: dict[str, str]) -> dict[str, set[str]]:
    known = set(texts)
    return {module: imports(module, text, known) for module, text in texts.items()}


def backward_imports(edges: dict[str, set[str]]) -> list[str]:
    """Imports from an earlier stage into a later one, as "a (stage) imports b (stage)"."""
    found = []
    for module, targets in sorted(edges.items()):
        for target in sorted(targets):
            if stage_of(target) > stage_of(module):
                found.append(f"{module} ({STAGES[stage_of(module)][0]}) imports {target} "
                             f"({STAGES[stage_of(target)][0]}, a later stage)")
    return found


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The import cycles: strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in sorted(edges.get(node, ())):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1 or node in edges.get(node, ()):
                found.append(sorted(component))

    for node in sorted(edges):
        if node not in index:
            visit(node)
    return found


def test_every_module_has_a_stage():
    unplaced = []
    for module in sources():
        try:
            stage_of(module)
        except LookupError as exc:
            unplaced.append(str(exc))
    assert not unplaced


def test_imports_run_from_later_stages_to_earlier_ones_only():
    assert backward_imports(graph(sources())) == []


def test_no_import_cycles():
    assert cycles(graph(sources())) == []


def test_the_checks_catch_a_backward_import_and_a_cycle():
    texts = sources()
    hostile = dict(texts)
    hostile["foldfab.job"] += "\nfrom foldfab.fabrication.spec import parse_fabrication\n"
    assert backward_imports(graph(hostile)) == [
        "foldfab.job (job) imports foldfab.fabrication.spec (fabrication, a later stage)"]
    assert ["foldfab.fabrication.spec", "foldfab.job"] in cycles(graph(hostile))
    inside = dict(texts)
    inside["foldfab.geometry.reflection"] += "\ndef late():\n    from foldfab import design\n"
    assert backward_imports(graph(inside)) == [
        "foldfab.geometry.reflection (geometry) imports foldfab.design (design, a later stage)"]
    relative = dict(texts)
    relative["foldfab.sim.record"] += "\nif True:\n    from .device import Simulator\n"
    assert ["foldfab.sim.device", "foldfab.sim.record"] in cycles(graph(relative))
    with pytest.raises(LookupError, match="foldfab.newstage belongs to no stage"):
        stage_of("foldfab.newstage")


@pytest.mark.parametrize("module", sorted(sources()))
def test_modules_are_short(module):
    path = PACKAGE.parent / (module.replace(".", "/") + ".py")
    if not path.is_file():
        path = path.with_suffix("") / "__init__.py"
    lines = len(path.read_text(encoding="utf-8").splitlines())
    assert lines <= MAX_LINES or module in LONGER, \
        f"{module} has {lines} lines: split it by concept, or say in LONGER why one concept needs more"


@pytest.mark.parametrize("old, name, new", [
    ("foldfab.program", "write_program", "foldfab.programs.languages"),
    ("foldfab.interpret", "interpret", "foldfab.programs.interpret"),
    ("foldfab.urlhandler.protocol_sim", "Serial", "foldfab.plotting.urlhandler.protocol_sim"),
])
def test_moved_public_names_still_import_from_their_old_paths_with_a_warning(old, name, new):
    """The README's Python API: a moved name keeps its old path for one release, and says where it went."""
    code = (f"import warnings; warnings.simplefilter('always')\n"
            f"with warnings.catch_warnings(record=True) as seen:\n"
            f"    import importlib; old = importlib.import_module({old!r})\n"
            f"import {new} as new\n"
            f"assert getattr(old, {name!r}) is getattr(new, {name!r})\n"
            f"assert any(w.category is DeprecationWarning and {new.rsplit('.', 1)[0]!r} in str(w.message) "
            f"for w in seen), [str(w.message) for w in seen]\n")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=PACKAGE.parent)


def test_sim_opens_through_the_old_handler_package():
    """A pyserial configuration that names the old package still reaches ``sim://``."""
    code = ("import warnings, serial; warnings.simplefilter('ignore', DeprecationWarning)\n"
            "serial.protocol_handler_packages.append('foldfab.urlhandler')\n"
            "port = serial.serial_for_url('sim://hp7475a?time=instant', timeout=1)\n"
            "port.write(b'OI;'); reply = port.read_until(b'\\r')\n"
            "assert b'7475A' in reply, reply\n")
    subprocess.run([sys.executable, "-c", code], check=True, cwd=PACKAGE.parent)

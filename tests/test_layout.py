"""The codebase's shape, as ``docs/design.md`` ("Code layout") promises it to a reader: small
modules, numba kernels with short signatures, no import circle, argparse only in the CLI,
and every repository path the code and docs cite exists."""

from __future__ import annotations

import ast
import importlib
import inspect
import os
import re
import warnings

import pytest

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
PACKAGE = os.path.join(ROOT, "mjsound")

#: Module length, a guideline: above GUIDE_LINES a warning (split where a concept ends: a
#: class's collaborator, a measurement, a stage of a pipeline), above MAX_LINES a failure.
GUIDE_LINES = 600
MAX_LINES = 800
#: The README is a user's guide; method details and figures go to docs/.
README_MAX_LINES = 300
MAX_KERNEL_PARAMETERS = 12


def _modules() -> dict[str, str]:
    """``{dotted name: path}`` of every module of the package (a package as its ``__init__``)."""
    out = {}
    for folder, dirs, files in os.walk(PACKAGE):
        dirs[:] = [d for d in dirs if d != "__pycache__"]
        for f in files:
            if f.endswith(".py"):
                rel = os.path.relpath(os.path.join(folder, f), ROOT)[:-3].split(os.sep)
                if rel[-1] == "__init__":
                    rel = rel[:-1]
                out[".".join(rel)] = os.path.join(folder, f)
    return out


MODULES = _modules()


def _top_level_imports(name: str, path: str) -> set[str]:
    """The package modules ``name`` imports while it is imported (statements in functions and
    in ``if TYPE_CHECKING:`` blocks run later or never, and are left out)."""
    is_package = path.endswith("__init__.py")
    found = set()

    def resolve(level: int, module: str | None) -> str:
        if level == 0:
            return module or ""
        base = name.split(".") if is_package else name.split(".")[:-1]
        base = base[: len(base) - (level - 1)]
        return ".".join(base + ([module] if module else []))

    def visit(nodes):
        for node in nodes:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
                continue
            if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
                visit(node.orelse)
                continue
            if isinstance(node, ast.Import):
                found.update(a.name for a in node.names)
            elif isinstance(node, ast.ImportFrom):
                target = resolve(node.level, node.module)
                found.add(target)
                found.update(f"{target}.{a.name}" for a in node.names)
            visit(ast.iter_child_nodes(node))

    visit(ast.parse(open(path).read()).body)
    own = {m for m in found if m in MODULES}
    # a module's parent packages are being imported already when it is: not an edge of a circle
    return {m for m in own if not name.startswith(m + ".")} - {name}


def test_modules_are_short():
    """No module over MAX_LINES; a module over GUIDE_LINES is flagged (a warning in the test
    summary), to be split by concept, not squeezed under the line count."""
    lines = {n: sum(1 for _ in open(p)) for n, p in MODULES.items()}
    long = {n: k for n, k in lines.items() if k > GUIDE_LINES}
    if long:
        warnings.warn(f"modules over the {GUIDE_LINES}-line guideline: {long}; split each where a concept ends "
                      "(docs/design.md, \"Code layout\")", UserWarning, stacklevel=1)
    assert {n: k for n, k in long.items() if k > MAX_LINES} == {}


def test_the_readme_is_a_short_guide():
    """README.md stays a user's guide of at most README_MAX_LINES lines (details in docs/)."""
    n = sum(1 for _ in open(os.path.join(ROOT, "README.md"), encoding="utf-8"))
    assert n <= README_MAX_LINES, f"README.md has {n} lines (at most {README_MAX_LINES}): move details to docs/"


def test_no_numba_kernel_takes_more_than_12_parameters():
    from numba.core.registry import CPUDispatcher  # (njit_inner's dispatchers are ones too)

    kernels = {}
    for name in MODULES:
        if name.endswith("__main__"):
            continue
        module = importlib.import_module(name)
        for attr, value in vars(module).items():
            if isinstance(value, CPUDispatcher) and value.py_func.__module__ == name:
                kernels[f"{name}.{attr}"] = len(inspect.signature(value.py_func).parameters)
    assert len(kernels) > 50  # (the walk found the kernels: the step, render and modal ones)
    assert {k: n for k, n in kernels.items() if n > MAX_KERNEL_PARAMETERS} == {}


def test_the_package_has_no_import_circle():
    graph = {name: _top_level_imports(name, path) for name, path in MODULES.items()}
    assert "mjsound.sim.step" in graph["mjsound.sim.driver"]  # (the edges are found)
    state, circles = {}, []

    def walk(node, stack):
        state[node] = "open"
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                circles.append(stack[stack.index(nxt):] + [nxt])
            elif nxt not in state:
                walk(nxt, stack)
        stack.pop()
        state[node] = "done"

    for name in sorted(graph):
        if name not in state:
            walk(name, [])
    assert circles == []


def test_only_the_cli_imports_argparse():
    users = []
    for name, path in MODULES.items():
        tree = ast.parse(open(path).read())
        for node in ast.walk(tree):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module] if isinstance(node, ast.ImportFrom) else []
            if "argparse" in names and not name.startswith("mjsound.cli"):
                users.append(name)
    assert users == []


#: A path inside the repository, as code and documents cite one.
CITED = re.compile(r"(?<![\w/.-])((?:docs|scripts|tests|reports|assets|mjsound)/[\w./-]+\.(?:md|py|xml|json|png|csv|txt))")


#: Where code and documents cite repository paths and design sections.
CITING = ["mjsound", "scripts", "tests", "docs", "README.md", "CHANGELOG.md"]


def _text_files(where: str) -> list[str]:
    """The Python and Markdown files of ``where`` (a file or a folder of the repository)."""
    top = os.path.join(ROOT, where)
    if os.path.isfile(top):
        return [top]
    return [os.path.join(d, f) for d, _, fs in os.walk(top) if "__pycache__" not in d
            for f in fs if f.endswith((".py", ".md"))]


@pytest.mark.parametrize("where", CITING)
def test_every_cited_repository_path_exists(where):
    cited = {}
    for f in _text_files(where):
        for m in CITED.finditer(open(f, encoding="utf-8").read()):
            cited.setdefault(m.group(1).rstrip("."), os.path.relpath(f, ROOT))
    assert cited, f"no repository path cited in {where}"
    missing = {p: f for p, f in cited.items() if not os.path.exists(os.path.join(ROOT, p))}
    assert missing == {}


#: A section of the design document cited by name: ``docs/design.md`` ("Section") and the like.
CITED_SECTION = re.compile(r"design\.md`*[ ,(]*[\"“]([^\"”]+)[\"”]")


def test_every_cited_design_section_exists():
    headings = {line.lstrip("#").strip() for line in open(os.path.join(ROOT, "docs", "design.md"), encoding="utf-8")
                if line.startswith("#")}
    cited = {}
    for f in (f for where in CITING for f in _text_files(where)):
        if os.path.abspath(f) == os.path.abspath(__file__):
            continue  # (its own pattern and example are not citations)
        for m in CITED_SECTION.finditer(open(f, encoding="utf-8").read()):
            cited.setdefault(m.group(1), os.path.relpath(f, ROOT))
    assert "State records" in cited  # (the pattern finds the citations)
    assert {s: f for s, f in cited.items() if s not in headings} == {}


def test_commit_message_rule():
    """``scripts/check_commit_msg.py``: a subject over 72 characters or a second line that is
    not blank is named; a subject with a body after a blank line passes (git's comments
    ignored)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("check_commit_msg", os.path.join(ROOT, "scripts", "check_commit_msg.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    assert mod.problems("Split wrappers.py by concept\n\nWhy and figures.\n# a git comment " + "x" * 80) == []
    long = mod.problems("x" * 73)
    assert len(long) == 1 and "73 characters" in long[0]
    assert mod.problems("x" * 72) == []
    assert mod.problems("Subject\nno blank line") == ["the second line must be blank (subject, blank line, body)"]
    assert mod.problems("# only comments\n\n") == ["the message is empty"]

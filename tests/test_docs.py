"""The documentation: the site builds with no warning, the README stays a short user guide whose links resolve,
every page of docs/ is in the site's navigation, and no text points at tracker numbers instead of saying what it
means."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest

from conftest import ROOT

README_LIMIT = 10240  # bytes: the README is a user guide; the detail lives in docs/, the history in CHANGELOG.md
TRACKER_REFERENCE = re.compile(r"\bissue\s+#?\d+", re.IGNORECASE)
SCANNED = ("README.md", "CHANGELOG.md", "docs", "src", "tests")
NOT_SOURCE = ("__pycache__", ".pytest_cache", ".hypothesis")  # folders of generated files


@pytest.mark.slow
def test_the_site_builds_strictly(tmp_path):
    """``mkdocs build --strict``: a broken link or anchor, a page missing from the navigation, or an API page naming
    a module that does not exist fails the build."""
    try:
        import mkdocs  # noqa: F401
    except ImportError:
        pytest.skip("mkdocs is not installed; it comes with the test extra (bash setup.sh --test)")
    result = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--config-file", str(ROOT / "mkdocs.yml"),
         "--site-dir", str(tmp_path / "site")],
        cwd=ROOT, capture_output=True, text=True, timeout=600, env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})
    assert result.returncode == 0, f"mkdocs build --strict failed:\n{result.stderr[-4000:]}"
    assert (tmp_path / "site" / "index.html").is_file()


def test_the_readme_is_short():
    size = len((ROOT / "README.md").read_bytes())
    assert size <= README_LIMIT, f"README.md is {size} bytes, over {README_LIMIT}: move the detail into docs/"


def test_the_readmes_links_to_pages_resolve():
    text = (ROOT / "README.md").read_text()
    targets = re.findall(r"\]\(([^)#\s]+\.md)(?:#[^)]*)?\)", text)
    assert targets, "the README links to no page"
    missing = sorted({t for t in targets if not (ROOT / t).is_file()})
    assert not missing, f"README.md links to pages that do not exist: {missing}"


def _nav_pages(entries) -> set[str]:
    pages = set()
    for entry in entries:
        values = entry.values() if isinstance(entry, dict) else [entry]
        for value in values:
            pages |= {value} if isinstance(value, str) else _nav_pages(value)
    return pages


def test_every_docs_page_is_in_the_nav():
    import yaml

    config = yaml.safe_load((ROOT / "mkdocs.yml").read_text())
    listed = _nav_pages(config["nav"])
    docs = ROOT / config.get("docs_dir", "docs")
    pages = {p.relative_to(docs).as_posix() for p in docs.rglob("*.md")}
    assert not pages - listed, f"pages missing from mkdocs.yml's nav: {sorted(pages - listed)}"
    assert not listed - pages, f"nav entries with no page: {sorted(listed - pages)}"


def _scanned_files():
    for name in SCANNED:
        path = ROOT / name
        if path.is_file():
            yield path
        elif path.is_dir():
            for file in sorted(path.rglob("*")):
                parts = file.relative_to(ROOT).parts
                if file.is_file() and not any(p in NOT_SOURCE or p.endswith(".egg-info") for p in parts):
                    yield file


def test_no_text_refers_to_a_tracker_number():
    """Text says what a change or a bound is about, not which ticket asked for it: a reader has no tracker."""
    found = []
    for path in _scanned_files():
        data = path.read_bytes()
        if b"\0" in data:  # binary (images, compiled files)
            continue
        for number, line in enumerate(data.decode("utf-8", "replace").splitlines(), 1):
            match = TRACKER_REFERENCE.search(line)
            if match:
                found.append(f"{path.relative_to(ROOT)}:{number}: {match.group(0)}")
    assert not found, "tracker numbers in the text (say what is meant instead):\n" + "\n".join(found)


def test_the_readmes_python_runs(tmp_path):
    """The README's Python example, run as written on the shipped probe (copied in as probe.hdr)."""
    import shutil

    from lightprobe.data import default_probe_path

    block = re.search(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
    assert block, "the README has no Python example"
    shutil.copyfile(default_probe_path(), tmp_path / "probe.hdr")
    result = subprocess.run([sys.executable, "-c", block.group(1)], cwd=tmp_path, capture_output=True, text=True,
                            timeout=600, env={**os.environ, "LIGHTPROBE_PROGRESS": "0"})
    assert result.returncode == 0, result.stderr[-3000:]
    assert (tmp_path / "cube.exr").is_file() and (tmp_path / "sh.txt").read_text().count("(") == 9


def _api_modules() -> list[str]:
    """The modules the API reference documents (its ``::: module`` lines)."""
    return [line.split(":::", 1)[1].strip() for page in sorted((ROOT / "docs" / "api").glob("*.md"))
            for line in page.read_text().splitlines() if line.startswith(":::")]


def _public_functions(module: str):
    """(name, node) of each public function of ``module`` and each public method of its public classes."""
    import ast

    path = ROOT / "src" / (module.replace(".", "/") + ".py")
    if not path.is_file():
        path = path.with_suffix("") / "__init__.py"
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.FunctionDef) and not node.name.startswith("_"):
            yield node.name, node
        elif isinstance(node, ast.ClassDef) and not node.name.startswith("_"):
            for item in node.body:
                if isinstance(item, ast.FunctionDef) and not item.name.startswith("_"):
                    yield f"{node.name}.{item.name}", item


def _missing_sections(node) -> list[str]:
    """The numpydoc sections a function's docstring lacks: Parameters when it takes any (self and cls aside),
    Returns when it returns something (a property's docstring is its value's, and needs neither)."""
    import ast

    decorators = {getattr(d, "id", getattr(d, "attr", "")) for d in node.decorator_list}
    if "property" in decorators or "setter" in decorators:
        return []
    doc = ast.get_docstring(node) or ""
    args = node.args
    names = [a.arg for a in args.posonlyargs + args.args + args.kwonlyargs] + \
        [a.arg for a in (args.vararg, args.kwarg) if a is not None]
    missing = []
    if [n for n in names if n not in ("self", "cls")] and "Parameters\n----------" not in doc:
        missing.append("Parameters")
    returns = node.returns
    returns_nothing = returns is None or (isinstance(returns, ast.Constant) and returns.value is None)
    if not returns_nothing and "Returns\n-------" not in doc and "Yields\n------" not in doc:
        missing.append("Returns")
    return missing


def test_every_public_function_of_the_api_has_numpydoc_sections():
    """Every public function and method the API reference shows states its parameters and what it returns
    (numpydoc ``Parameters`` / ``Returns``), so the reference gives each one's conventions and units."""
    missing = [f"{module}.{name}: {', '.join(lacks)}" for module in _api_modules()
               for name, node in _public_functions(module) if (lacks := _missing_sections(node))]
    assert not missing, f"{len(missing)} without numpydoc sections:\n" + "\n".join(missing)


def test_the_numpydoc_check_sees_a_missing_section():
    import ast

    (plain,) = ast.parse('def f(x) -> int:\n    """Twice x."""\n').body
    (full,) = ast.parse('def f(x) -> int:\n    """Twice x.\n\n    Parameters\n    ----------\n    x : int\n'
                        '        A number.\n\n    Returns\n    -------\n    int\n        2x.\n    """\n').body
    assert _missing_sections(plain) == ["Parameters", "Returns"] and _missing_sections(full) == []

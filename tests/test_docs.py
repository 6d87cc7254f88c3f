"""Every public function and class is documented, and every public argument has a docstring entry."""

from __future__ import annotations

import importlib
import inspect
import pkgutil

import pytest

import delayform

#: every module of the package, so a new module is checked the day it arrives
MODULES = sorted(
    m.name.removeprefix("delayform.")
    for m in pkgutil.walk_packages(delayform.__path__, "delayform.")
    if m.name != "delayform.__main__"
)


def _public(module_name: str):
    module = importlib.import_module(f"delayform.{module_name}")
    for name in getattr(module, "__all__", []):
        obj = getattr(module, name)
        if inspect.isfunction(obj) or inspect.isclass(obj):
            yield f"{module_name}.{name}", obj


PUBLIC = [pair for m in MODULES for pair in _public(m)]


@pytest.mark.parametrize("qualname, obj", PUBLIC, ids=[q for q, _ in PUBLIC])
def test_public_object_is_documented(qualname, obj):
    doc = inspect.getdoc(obj)
    assert doc and len(doc.split()) >= 3, f"{qualname} has no docstring"
    if inspect.isfunction(obj):
        params = [
            p
            for p in inspect.signature(obj).parameters
            if p not in ("self", "cls") and not p.startswith("_")
        ]
        missing = [p for p in params if p not in doc]
        assert not missing, f"{qualname}: arguments without a docstring entry: {missing}"


def test_package_exports_resolve():
    for name in delayform.__all__:
        assert getattr(delayform, name) is not None


def test_readme_python_example_runs():
    import pathlib
    import re

    readme = pathlib.Path(__file__).resolve().parents[1] / "README.md"
    blocks = re.findall(r"```python\n(.*?)```", readme.read_text(encoding="utf-8"), flags=re.S)
    assert blocks, "README has no Python example"
    for block in blocks:
        exec(compile(block, "README.md", "exec"), {})

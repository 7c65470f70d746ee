"""The public API's documentation: numpydoc sections on every name of ``editor.core``, and
every docstring example of the core packages run (they must print what they say)."""

from __future__ import annotations

import doctest
import importlib
import inspect
import pkgutil
import re

import pytest

import editor
import editor.core

CORE_PACKAGES = ("editor.engine", "editor.formats", "editor.study", "editor.synthesis",
                 "editor.core")
#: Documented (with examples) in the editor.core module docstring instead of their own:
#: constants have no docstring of their own.
IN_MODULE_DOC = {"FAPS", "MAX_PIXELS"}
#: Face methods a script uses besides the class itself.
FACE_METHODS = ("from_image", "deform", "render")


def _core_modules() -> list[str]:
    names = []
    for pkg in CORE_PACKAGES:
        mod = importlib.import_module(pkg)
        names.append(pkg)
        if hasattr(mod, "__path__"):
            names += [m.name for m in pkgutil.iter_modules(mod.__path__, pkg + ".")]
    for extra in ("errors", "resources", "safeio"):
        names.append(f"editor.{extra}")
    return names


def _sections(doc: str) -> set[str]:
    """numpydoc section headings of a docstring (a line underlined by dashes)."""
    return set(re.findall(r"^\s*([A-Z][A-Za-z ]+)\n\s*-{3,}\s*$", doc, re.M))


def _public_objects() -> list[tuple[str, object]]:
    out: list[tuple[str, object]] = []
    for name in editor.core.__all__:
        if name in IN_MODULE_DOC:
            continue
        obj = getattr(editor.core, name)
        out.append((name, obj))
        if name == "Face":
            out += [(f"Face.{m}", getattr(obj, m)) for m in FACE_METHODS]
    return out


@pytest.mark.parametrize("name,obj", _public_objects(), ids=[n for n, _ in _public_objects()])
def test_public_name_has_numpydoc_sections_and_an_example(name, obj):
    doc = inspect.getdoc(obj) or ""
    sections = _sections(doc)
    assert "Examples" in sections and ">>>" in doc.split("Examples", 1)[1], name
    if inspect.isclass(obj) and issubclass(obj, Exception):
        return  # an error's example shows where it is raised
    target = inspect.unwrap(obj)  # standard_mesh is cached
    if getattr(target, "_is_protocol", False):  # an interface: what implementations provide
        assert "Attributes" in sections, f"{name}: no Attributes section"
        return
    params = [p for p in inspect.signature(target).parameters if p not in ("self", "cls")]
    if params:  # a dataclass documents its fields (= its parameters) as Attributes
        fields = "Attributes" if hasattr(target, "__dataclass_fields__") else "Parameters"
        assert {"Parameters", fields} & sections, f"{name}: no Parameters section"
    if inspect.isfunction(target) or inspect.ismethod(target):
        returns = inspect.signature(target).return_annotation
        if returns not in (None, "None"):
            assert "Returns" in sections, f"{name}: no Returns section"


def test_names_without_own_docstring_are_shown_in_the_module_doc():
    doc = editor.core.__doc__ or ""
    examples = "\n".join(line for line in doc.splitlines()
                         if line.startswith((">>>", "...")))
    for name in IN_MODULE_DOC:
        assert re.search(rf"\b{name}\b", examples) or re.search(
            rf"\b{name}\b", doc) and name in doc.split("Examples", 1)[1], name
    assert "__all__" in doc  # says what the public API is


def _doctests() -> list[doctest.DocTest]:
    finder = doctest.DocTestFinder(exclude_empty=True)
    tests = []
    for modname in _core_modules():
        mod = importlib.import_module(modname)
        tests += [t for t in finder.find(mod, modname) if t.examples]
    return sorted(tests, key=lambda t: t.name)


DOCTESTS = _doctests()


def test_the_public_api_examples_are_collected():
    names = {t.name for t in DOCTESTS}
    for expected in ("editor.core", "editor.engine.face.Face", "editor.engine.face.Face.render",
                     "editor.formats.fapfile.read_fap", "editor.errors.NoFaceError"):
        assert expected in names


@pytest.mark.parametrize("test", DOCTESTS, ids=[t.name for t in DOCTESTS])
def test_docstring_example_runs(test):
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS)
    out: list[str] = []
    result = runner.run(test, out=out.append, clear_globs=True)
    assert result.failed == 0, "".join(out)

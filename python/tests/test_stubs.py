"""The type stubs and docstrings cover the public API."""

import ast
from pathlib import Path

import rodtrack

STUB = Path(__file__).resolve().parents[1] / "rodtrack" / "_rodtrack.pyi"


def stub_classes():
    tree = ast.parse(STUB.read_text())
    return {n.name: n for n in tree.body if isinstance(n, ast.ClassDef)}


def test_the_stubs_list_every_row_column():
    rows = stub_classes()["Rows"]
    props = {n.name for n in rows.body if isinstance(n, ast.FunctionDef)}
    missing = [c for c in rodtrack.COLUMNS if c not in props]
    assert not missing, f"columns missing from _rodtrack.pyi's Rows: {missing}"


def test_every_public_item_is_stubbed_and_documented():
    tree = ast.parse(STUB.read_text())
    stubbed = {n.name for n in tree.body if isinstance(n, (ast.ClassDef, ast.FunctionDef))}
    stubbed |= {t.target.id for t in tree.body if isinstance(t, ast.AnnAssign)}
    for name in rodtrack.__all__:
        obj = getattr(rodtrack, name)
        if name != "__version__":
            assert name in stubbed, f"{name} has no stub"
        if callable(obj):
            assert obj.__doc__ and obj.__doc__.strip(), f"{name} has no docstring"
            for attr, member in vars(obj).items() if isinstance(obj, type) else []:
                if attr.startswith("_"):
                    continue
                assert member.__doc__ and member.__doc__.strip(), f"{name}.{attr} has no docstring"
    assert (STUB.parent / "py.typed").exists()

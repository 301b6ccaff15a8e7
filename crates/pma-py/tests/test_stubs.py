"""The type stubs describe the module: every name and method in one is in the other, with
the same parameters."""
import ast
import inspect
import pathlib
import sys

import pma_exo

STUB = pathlib.Path(__file__).resolve().parents[1] / "python" / "pma_exo" / "__init__.pyi"


def stub_tree():
    return ast.parse(STUB.read_text())


def params(node):
    return [a.arg for a in node.args.args if a.arg != "self"]


def test_every_function_and_class_of_the_stubs_exists_with_its_parameters():
    for node in stub_tree().body:
        if isinstance(node, ast.FunctionDef):
            runtime = getattr(pma_exo, node.name)
            assert list(inspect.signature(runtime).parameters) == params(node), node.name
        elif isinstance(node, ast.ClassDef):
            cls = getattr(pma_exo, node.name)
            for item in node.body:
                if isinstance(item, ast.FunctionDef):
                    if item.name == "__init__":
                        # An abi3 class on Python 3.9 carries no constructor signature
                        # (the limited API gained it in 3.10): checked from 3.10 on.
                        if sys.version_info >= (3, 10):
                            assert list(inspect.signature(cls).parameters) == params(item), cls
                    else:
                        assert hasattr(cls, item.name), f"{node.name}.{item.name}"
                        member = getattr(cls, item.name)
                        if callable(member) and not isinstance(member, property):
                            assert list(inspect.signature(member).parameters)[1:] == params(item), item.name


def test_every_public_name_has_a_stub():
    stubbed = {
        n.name if hasattr(n, "name") else n.targets[0].id if isinstance(n, ast.Assign) else n.target.id
        for n in stub_tree().body
        if isinstance(n, (ast.FunctionDef, ast.ClassDef, ast.Assign, ast.AnnAssign))
    }
    assert set(pma_exo.__all__) <= stubbed
    for name in ("Bench", "Leg"):
        cls = getattr(pma_exo, name)
        stub = next(n for n in stub_tree().body if isinstance(n, ast.ClassDef) and n.name == name)
        methods = {i.name for i in stub.body if isinstance(i, ast.FunctionDef)}
        public = {m for m in dir(cls) if not m.startswith("_")}
        assert public <= methods, public - methods

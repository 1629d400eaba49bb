"""The functions of a Python source text as the architecture tests walk them."""
import ast


def functions(text: str):
    """(qualified name, node) of every function in ``text``: methods as ``Class.name``,
    nested functions as ``outer.inner``; classes give their name to what they hold."""
    out = []

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = f"{prefix}{child.name}"
                if not isinstance(child, ast.ClassDef):
                    out.append((name, child))
                visit(child, f"{name}.")
            else:
                visit(child, prefix)

    visit(ast.parse(text), "")
    return out

"""Generates the CLI reference page (``cli.md``) of the docs site from the ``bpmcal``
command's own parser (``bpmcal.cli.build_parser``), so it cannot drift from the code.
Run by the mkdocs-gen-files plugin during ``mkdocs build`` (mkdocs.yml); needs bpmcal
importable (``pip install -e .``, or ``PYTHONPATH=src``)."""
import argparse
import os

import mkdocs_gen_files

os.environ["COLUMNS"] = "100"  # argparse wraps help to the terminal: a fixed width

from bpmcal.cli import build_parser  # noqa: E402

parser = build_parser()
sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
helps = {c.dest: c.help for c in sub._choices_actions}

with mkdocs_gen_files.open("cli.md", "w") as f:
    f.write("# The `bpmcal` command\n\n"
            "Generated from `bpmcal.cli.build_parser()` when the site is built: each "
            "subcommand's `--help`. Exit codes and error messages: "
            "[troubleshooting](troubleshooting.md).\n\n")
    f.write("| command | what |\n|---|---|\n")
    for name in helps:
        f.write(f"| [`{name}`](#bpmcal-{name}) | {helps[name] or ''} |\n")
    for name in helps:
        f.write(f"\n## bpmcal {name}\n\n```text\n{sub.choices[name].format_help()}```\n")

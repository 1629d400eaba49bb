"""Config keys renamed with a one-release deprecation (bpmcal.study.config.RENAMED_KEYS):
an old key still works, with exactly one line saying what to use instead, and gives the
same validated config as its new name; giving both is an error naming both."""
import copy
import json
import re
import shlex

import pytest
import yaml
from support.repo import REPO, SCHEMA, copy_workflow, merged_config, run_snakemake

from bpmcal.study.config import RENAMED_KEYS, ConfigError, translate_deprecated, validate_config

PAIRS = sorted((".".join(o), ".".join(n)) for o, n in RENAMED_KEYS.items())


def _line(old, new):
    return f"config key {old} is deprecated: use {new} ({old} will be removed in the next release)"


def _with_old_names(cfg: dict, pairs=PAIRS, fill=True) -> dict:
    """``cfg`` (new names) with the keys of ``pairs`` under their old names, each in its
    place in its section; a key ``cfg`` lacks is added at its schema default (``fill``) or
    left out (an overlay)."""
    cfg = copy.deepcopy(cfg)
    for old, new in pairs:
        *path, key_new = new.split(".")
        key_old = old.split(".")[-1]
        section = cfg
        for k in path:
            if k not in section and not fill:
                section = {}
                break
            section = section.setdefault(k, {})
        if key_new not in section:
            if not fill:
                continue
            section[key_new] = copy.deepcopy(_schema_default(new))  # left to the schema
        items = [(key_old if k == key_new else k, v) for k, v in section.items()]
        section.clear()
        section.update(items)
    return cfg


def _schema_default(key):
    node = yaml.safe_load(SCHEMA.read_text())
    for k in key.split("."):
        node = node["properties"][k]
    return node["default"]


def _validated(cfg):
    notes = []
    out = validate_config(cfg, SCHEMA, base_dir=REPO, note=notes.append)
    return out, notes


def test_every_rename_keeps_its_section_and_the_new_names_are_in_the_schema():
    schema = yaml.safe_load(SCHEMA.read_text())
    for old, new in RENAMED_KEYS.items():
        assert old[:-1] == new[:-1] and old != new
        node = schema
        for k in new:
            node = node["properties"][k]
        node = schema
        for k in old[:-1]:
            node = node["properties"][k]
        assert old[-1] not in node["properties"], f"{'.'.join(old)} is still in the schema"


@pytest.mark.parametrize("old, new", PAIRS)
def test_an_old_key_gives_one_line_and_the_same_validated_config(old, new):
    want, quiet = _validated(merged_config("config.yaml"))
    assert quiet == []  # the shipped config uses the new names
    got, notes = _validated(_with_old_names(merged_config("config.yaml"), [(old, new)]))
    assert notes == [_line(old, new)]
    assert got == want
    assert list(got) == list(want)  # a renamed section keeps its place


def test_a_config_of_the_previous_release_validates_to_the_same_config():
    """Every old name at once (config/config.yaml as it was written before the renames):
    one line per old key, in RENAMED_KEYS order, and the same validated config."""
    want, _ = _validated(merged_config("config.yaml"))
    got, notes = _validated(_with_old_names(merged_config("config.yaml")))
    assert notes == [_line(".".join(o), ".".join(n)) for o, n in RENAMED_KEYS.items()]
    assert got == want


def test_the_line_goes_to_stderr_once(capsys):
    cfg = _with_old_names(merged_config("config.yaml"), [("calibration.ratio",
                                                          "calibration.strength_ratio")])
    validate_config(cfg, SCHEMA, base_dir=REPO)
    validate_config(cfg, SCHEMA, base_dir=REPO)  # translated in place: no second line
    out, err = capsys.readouterr()
    assert out == ""
    assert err == _line("calibration.ratio", "calibration.strength_ratio") + "\n"


@pytest.mark.parametrize("old, new", PAIRS)
def test_an_old_key_beside_its_new_name_is_an_error_naming_both(old, new):
    cfg = _with_old_names(merged_config("config.yaml"), [(old, new)])
    *path, key_new = new.split(".")
    section = cfg
    for k in path:
        section = section[k]
    section[key_new] = copy.deepcopy(section[old.split(".")[-1]])
    notes = []
    with pytest.raises(ConfigError) as e:
        validate_config(cfg, SCHEMA, base_dir=REPO, note=notes.append)
    msg = str(e.value)
    assert f"{old} and {new} both given" in msg and f"keep only {new}" in msg, msg
    assert notes == []


def test_an_overlay_with_an_old_section_over_the_shipped_config_names_both():
    """--configfile merges an overlay over config/config.yaml: an overlay written with
    ``ucs:`` gives both sections, and the error says where to rename."""
    cfg = merged_config("config.yaml")
    cfg["ucs"] = {"platen_velocity": 0.1}
    with pytest.raises(ConfigError, match=r"ucs and compression both given.*rename ucs"):
        validate_config(cfg, SCHEMA, base_dir=REPO, note=lambda line: None)


def test_translate_deprecated_leaves_a_config_without_old_keys_alone():
    cfg = merged_config("config.yaml")
    before = copy.deepcopy(cfg)
    notes = []
    assert translate_deprecated(cfg, notes.append) is cfg
    assert cfg == before and notes == []
    assert translate_deprecated({}, notes.append) == {} and notes == []
    assert translate_deprecated({"resources": None}, notes.append) == {"resources": None}


def test_config_readme_lists_every_rename():
    readme = (REPO / "config" / "README.md").read_text()
    for old, new in PAIRS:
        assert re.search(rf"\| `{re.escape(old)}` \| `{re.escape(new)}` \|", readme), old


# ------------------------------------------------------------------ through the workflow
def _commands(r) -> list[str]:
    """The shell commands of a dry run, sorted; the report's config text (the validated
    config) compared as data, not by its key order."""
    out = []
    for ln in (r.stdout + r.stderr).splitlines():
        if "Shell command: " not in ln or ln.endswith("Shell command: None"):
            continue
        argv = shlex.split(ln.split("Shell command: ", 1)[1])
        if "--config-json" in argv:
            i = argv.index("--config-json") + 1
            argv[i] = json.dumps(json.loads(argv[i]), sort_keys=True)
        out.append(shlex.join(argv))
    return sorted(out)


@pytest.mark.slow  # two Snakemake dry runs of the smoke study
def test_the_workflow_runs_an_old_config_as_the_new_one(tmp_path):
    """config/config.yaml and config/smoke.yaml written with the old names: the same jobs
    and commands as the shipped ones, and one deprecation line per old key."""
    new = copy_workflow(tmp_path / "new")
    old = copy_workflow(tmp_path / "old")
    cfg = yaml.safe_load((REPO / "config" / "config.yaml").read_text())
    (old / "config" / "config.yaml").write_text(yaml.safe_dump(_with_old_names(cfg),
                                                               sort_keys=False))
    smoke = yaml.safe_load((REPO / "config" / "smoke.yaml").read_text())
    (old / "config" / "smoke.yaml").write_text(yaml.safe_dump(
        _with_old_names(smoke, fill=False), sort_keys=False))
    args = ("-n", "-p", "--configfile", "config/smoke.yaml")
    r_new, r_old = run_snakemake(new, *args, timeout=300), run_snakemake(old, *args, timeout=300)
    assert r_new.returncode == 0, r_new.stderr[-3000:]
    assert r_old.returncode == 0, r_old.stderr[-3000:]
    assert _commands(r_old) == _commands(r_new) != []
    for o, n in PAIRS:
        assert (r_old.stdout + r_old.stderr).count(_line(o, n)) == 1, o
        assert "deprecated" not in r_new.stdout + r_new.stderr

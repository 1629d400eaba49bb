"""Which ready job Snakemake starts first: workflow/rules/common.smk's PRIORITY, the longest
jobs first, so that short jobs fill the cores at the end instead of a long one running
alone (issue 53). Every priority is a rule's own, and every DEM rule that runs a loop of
tests comes before the one-test jobs."""
import ast
import re

from support.repo import REPO

RULES = REPO / "workflow" / "rules"


def _priority() -> dict:
    text = (RULES / "common.smk").read_text()
    m = re.search(r"^PRIORITY = (\{.*?^\})", text, re.M | re.S)
    assert m, "common.smk defines no PRIORITY"
    return ast.literal_eval(m.group(1))


def _rule_priorities() -> dict:
    """rule name -> the PRIORITY key its ``priority:`` names (rules without one left out)."""
    out = {}
    for f in sorted(RULES.glob("*.smk")):
        for block in re.split(r"^(?=rule \w+:)", f.read_text(), flags=re.M)[1:]:
            name = re.match(r"rule (\w+):", block).group(1)
            m = re.search(r"^    priority: PRIORITY\[\"(\w+)\"\]", block, re.M)
            if m:
                out[name] = m.group(1)
    return out


def test_every_priority_is_its_rules_own_and_used():
    pri, used = _priority(), _rule_priorities()
    assert all(rule == key for rule, key in used.items()), used
    assert set(used.values()) == set(pri), set(pri) ^ set(used.values())


def test_the_loops_start_before_the_one_test_jobs():
    pri = _priority()
    loops = ("posterior_predictive", "verify", "transfer", "posterior", "fresh_seeds")
    single = ("sample", "triaxial", "sweep_ucs")
    assert min(pri[k] for k in loops) > max(pri[k] for k in single), pri
    assert all(v > 0 for v in pri.values())  # above the analysis jobs' default 0

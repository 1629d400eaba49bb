"""Seeds side by side: what ``--threads N`` buys a stage that runs many packing seeds.

    python benchmarks/seed_pool.py [--params benchmarks/fj_base_card.yaml] [--scale 0.3]
        [--seeds 4] [--repeat 3] [--json benchmarks/results/results_seed_pool_DATE.json]

``bpmcal scatter`` (the UCS test of one parameter set on ``--seeds`` packing seeds; the
closed loop's rounds and the fresh-seed check run their seeds the same way,
``bpmcal.stages.pool``) runs in one invocation with ``--threads 1`` (one seed after the
other, one numba thread: what every multi-seed job did before) and ``--threads 2`` (two
seeds at once, one worker process each), alternating, ``--repeat`` times each, on cached
packings (a warm-up run relaxes them first). Per mode: the median wall time, seeds per
minute, CPU time and the peak memory of the largest process (``os.wait4``: the command
and its workers), with the ratio of the medians; and whether both modes wrote the same
responses (they must: the pool changes where a run runs, not what it computes).
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from peers import host_info  # noqa: E402


def _run(card: Path, seeds: list[int], threads: int, out: Path, scale: float, cache: Path) -> dict:
    runs = [out / f"seed{s}.h5" for s in seeds]
    cmd = [sys.executable, "-m", "bpmcal.cli", "scatter", "--card", str(card),
           "--seeds", ",".join(map(str, seeds)), "--runs", *map(str, runs),
           "--seed-runs", str(out / "seed_runs.csv"), "--table", str(out / "scatter.csv"),
           "--scale", str(scale), "--specimen-cache", str(cache), "--threads", str(threads)]
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, ru = os.wait4(p.pid, 0)
    wall = time.perf_counter() - t0
    err = p.stderr.read().decode()
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"{' '.join(cmd)} failed:\n{err}")
    return {"wall_s": wall, "cpu_s": ru.ru_utime + ru.ru_stime, "max_rss_mb": ru.ru_maxrss / 1024,
            "responses": (out / "seed_runs.csv").read_text()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--params", default=str(HERE / "fj_base_card.yaml"),
                    help="a parameter file (bpmcal ucs --params); default the flat-joint base card")
    ap.add_argument("--scale", type=float, default=0.3)
    ap.add_argument("--seeds", type=int, default=4)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", default=None)
    a = ap.parse_args(argv)

    import yaml

    from bpmcal.io.card import write_card

    params = yaml.safe_load(Path(a.params).read_text())
    seeds = list(range(1, a.seeds + 1))
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        card = tmp / "card.yaml"
        write_card(card, {"specimen": "bench", "parameters": params})
        cache = tmp / "packings"
        (tmp / "warm").mkdir()
        _run(card, seeds, 2, tmp / "warm", a.scale, cache)  # relax the packings once
        res: dict[int, list[dict]] = {1: [], 2: []}
        for r in range(a.repeat):
            for t in (1, 2):
                d = tmp / f"t{t}_r{r}"
                d.mkdir()
                res[t].append(_run(card, seeds, t, d, a.scale, cache))
                print(f"repeat {r + 1}, --threads {t}: {res[t][-1]['wall_s']:.1f} s wall, "
                      f"{res[t][-1]['cpu_s']:.1f} s CPU", file=sys.stderr)
    same = len({x["responses"] for t in res for x in res[t]}) == 1
    rows = {}
    for t in (1, 2):
        wall = statistics.median(x["wall_s"] for x in res[t])
        rows[t] = {"threads": t, "wall_s": wall, "seeds_per_min": 60 * len(seeds) / wall,
                   "cpu_s": statistics.median(x["cpu_s"] for x in res[t]),
                   "max_rss_mb": max(x["max_rss_mb"] for x in res[t]),
                   "walls_s": [round(x["wall_s"], 2) for x in res[t]]}
    ratio = rows[1]["wall_s"] / rows[2]["wall_s"]
    host = host_info()
    print(f"host: {host.get('cpu_model')}, {host.get('cores')} CPUs, load {os.getloadavg()[0]:.2f}")
    print(f"{len(seeds)} seeds of {a.params} at scale {a.scale}, median of {a.repeat}")
    print("| --threads | wall [s] | seeds/min | CPU [s] | peak RSS, largest process [MB] |")
    print("|---|---|---|---|---|")
    for t, r in rows.items():
        print(f"| {t} | {r['wall_s']:.1f} | {r['seeds_per_min']:.2f} | {r['cpu_s']:.1f} | "
              f"{r['max_rss_mb']:.0f} |")
    print(f"speed-up, --threads 2 over 1 (same invocation): {ratio:.2f}x; "
          f"identical responses: {same}")
    if a.json:
        Path(a.json).write_text(json.dumps({
            "host": host, "load_after": os.getloadavg(), "params": a.params, "scale": a.scale,
            "seeds": seeds, "repeat": a.repeat, "modes": list(rows.values()),
            "speedup": ratio, "identical": same}, indent=2))
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())

#!/usr/bin/env python3
"""`lblight submit` on a real one-node Slurm (scripts/local-slurm.sh, docs/scale-out.md): the default
scene and the forest example (models and coarse forest lattices) baked as a job array plus a merge
equal a one-machine bake bit for bit; a unit made to fail
cancels the merge (it does not hang) and shows as failed in `lblight status`; `submit --resume` reruns
only that unit (its log says it baked, no other unit ran) and the result is still identical; the
merge refuses a partial of another scene; the forest baked across 2 MPI ranks under
`srun --mpi=pmix` (`--backend mpi`) equals its one-machine bake. Skipped (exit 77, saying why) where Slurm cannot be
installed or started.

usage: check_submit.py LBLIGHT SOURCE_DIR WORK_DIR"""
import json
import os
import re
import shutil
import subprocess
import sys
import time
from pathlib import Path

SKIP = 77
FINAL = {"COMPLETED", "FAILED", "CANCELLED", "TIMEOUT", "OUT_OF_MEMORY", "NODE_FAIL", "PREEMPTED", "BOOT_FAIL",
         "DEADLINE"}
lblight, source, work = sys.argv[1], Path(sys.argv[2]).resolve(), Path(sys.argv[3]).resolve()
scene = source / "configs" / "default.json"
# Two of the default scene's solutions (B00 and B06, both models): the same code paths as all 19,
# in well under a minute on 2 cores.
solutions = ["--solutions", "0,6"]
other_scene = source / "tests" / "scenes" / "small-paper.json"
failures = []
t_start = time.monotonic()


def check(ok, what):
    print(("ok: " if ok else "FAIL: ") + what, flush=True)
    if not ok:
        failures.append(what)


def run(*args, expect=0):
    r = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    if expect is not None and r.returncode != expect:
        print(r.stdout + r.stderr)
        raise SystemExit(f"FAIL: {' '.join(map(str, args))}: exit code {r.returncode}, expected {expect}")
    return r


def jobs(job_ids):
    """JobState per job (array tasks as '<array>_<task>'), from scontrol, not accounting."""
    out = run("scontrol", "-o", "show", "job", expect=None).stdout
    states = {}
    for line in out.splitlines():
        f = dict(re.findall(r"(\w+)=(\S*)", line))
        if f.get("ArrayJobId") in job_ids and f.get("ArrayTaskId", "").isdigit():
            states[f"{f['ArrayJobId']}_{f['ArrayTaskId']}"] = f.get("JobState")
        elif f.get("JobId") in job_ids and "ArrayJobId" not in f:
            states[f["JobId"]] = f.get("JobState")
    return states


def wait(job_ids, expected_jobs, limit=240):
    """Polls until `expected_jobs` jobs and tasks of `job_ids` are in a final state (bounded)."""
    t0 = time.monotonic()
    while time.monotonic() - t0 < limit:
        states = jobs(job_ids)
        if len(states) >= expected_jobs and all(s in FINAL for s in states.values()):
            print(f"jobs {sorted(job_ids)} finished in {time.monotonic() - t0:.1f} s: {states}", flush=True)
            return states
        time.sleep(0.5)
    raise SystemExit(f"FAIL: jobs {job_ids} not finished after {limit} s: {jobs(job_ids)}")


def submit(*extra):
    r = run(lblight, "submit", scene, *solutions, "--slurm", "--cpus-per-task", "1", "-o", work / "sub", *extra)
    print(r.stdout, end="")
    array, merge = r.stdout.strip().splitlines()[-1].split()[1:3]
    return array, merge, r.stdout


def status():
    return {u["name"]: u["state"] for u in json.loads(run(lblight, "status", work / "sub", "--json").stdout)["units"]}


def main():
    cluster = work / "cluster"
    # daemons a killed earlier run left behind would hold the ports: stopped by their pid files
    subprocess.run([source / "scripts" / "local-slurm.sh", "stop", cluster], capture_output=True)
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir(parents=True)
    r = subprocess.run([source / "scripts" / "local-slurm.sh", "start", cluster], capture_output=True, text=True)
    if r.returncode != 0:
        print("SKIPPED: no local Slurm cluster here: " + (r.stderr.strip() or f"exit code {r.returncode}"))
        return SKIP
    os.environ["SLURM_CONF"] = str(cluster / "slurm.conf")
    print(f"cluster up in {time.monotonic() - t_start:.1f} s", flush=True)
    try:
        checks()
    finally:
        subprocess.run([source / "scripts" / "local-slurm.sh", "stop", cluster])
    print(f"{time.monotonic() - t_start:.1f} s in all")
    return 1 if failures else 0


def checks():
    t0 = time.monotonic()
    run(lblight, "-q", "bake", scene, *solutions, "--threads", "1", "-o", work / "single")
    print(f"one-machine bake: {time.monotonic() - t0:.1f} s", flush=True)

    # The scripts: sized from the estimates, the merge cancelled by a failed unit, GPUs for cuda.
    dry = run(lblight, "submit", scene, *solutions, "--slurm", "--cpus-per-task", "1", "--dry-run", "-o",
              work / "sub").stdout
    units_script = (work / "sub" / "slurm" / "units.sbatch").read_text()
    merge_script = (work / "sub" / "slurm" / "merge.sbatch").read_text()
    check(re.search(r"#SBATCH --mem=\d+M", units_script) and re.search(r"#SBATCH --time=\d-\d\d:\d\d:00", units_script),
          "the array script requests memory and time from the estimates")
    check("--kill-on-invalid-dep=yes" in merge_script and "afterok" in dry and "gpus" not in units_script,
          "the merge runs afterok the array and is cancelled by a failed unit; no GPU on the cpu backend")
    run(lblight, "submit", scene, "--slurm", "--backend", "cuda", "--dry-run", "--no-timing", "-o", work / "gpu")
    check("#SBATCH --gpus-per-task=1" in (work / "gpu" / "slurm" / "units.sbatch").read_text(),
          "--backend cuda requests a GPU per task")

    # One unit made to fail: its output folder holds a file that is not lblight's, so its bake
    # refuses to replace it (exit 2).
    blocker = work / "sub" / "parts" / "cumulus" / "note.txt"
    blocker.parent.mkdir(parents=True)
    blocker.write_text("not lblight's\n")
    t0 = time.monotonic()
    array, merge, _ = submit()
    states = wait({array, merge}, 3)
    check(states.get(f"{array}_0") == "COMPLETED" and states.get(f"{array}_1") == "FAILED",
          "unit tree completed, unit cumulus failed")
    check(states.get(merge) == "CANCELLED", f"the merge was cancelled, not left pending ({states.get(merge)})")
    st = status()
    check(st == {"tree": "done", "cumulus": "failed"}, f"status reads the parts: {st}")
    check(not (work / "sub" / "bake").exists(), "nothing merged")
    print(f"first submission: {time.monotonic() - t0:.1f} s", flush=True)

    blocker.unlink()
    t0 = time.monotonic()
    array2, merge2, out = submit("--resume")
    check("done: skipped" in out and "array task 1" in out, "--resume submits only the unfinished unit")
    states = wait({array2, merge2}, 2)
    check(states == {f"{array2}_1": "COMPLETED", merge2: "COMPLETED"}, f"rerun and merge completed: {states}")
    logs = sorted(p.name for p in (work / "sub" / "logs").glob(f"*.{array2}_*.log"))
    check(logs == [f"cumulus.{array2}_1.log"], f"only cumulus ran again: {logs}")
    log = (work / "sub" / "logs" / f"cumulus.{array2}_1.log").read_text()
    check("baking it" in log, "its log says it baked the unit")
    print(f"resumed submission: {time.monotonic() - t0:.1f} s", flush=True)
    st = status()
    check(st == {"tree": "done", "cumulus": "done"}, f"status: every unit done: {st}")
    same = run(lblight, "compare", "--exact", work / "single", work / "sub" / "bake", expect=None)
    print(same.stdout, end="")
    check(same.returncode == 0, "the merged bake equals the one-machine bake bit for bit")
    # A unit task run again with --resume finds its partial and does not recompute it.
    again = run(lblight, "bake", scene, *solutions, "--only", "tree", "--resume", "-o", work / "sub" / "parts" / "tree")
    check("not recomputed" in again.stderr, "bake --only --resume leaves a finished unit alone")

    # The forest example: its models and coarse forest lattices as units (one solution keeps it short).
    forest, forest_args = source / "configs" / "forest.json", ["--solutions", "6"]
    run(lblight, "-q", "bake", forest, *forest_args, "--threads", "1", "-o", work / "forest-single")
    t0 = time.monotonic()
    r = run(lblight, "submit", forest, *forest_args, "--slurm", "--cpus-per-task", "1", "-o", work / "forest-sub")
    array, merge = r.stdout.strip().splitlines()[-1].split()[1:3]
    states = wait({array, merge}, 6)
    check(all(s == "COMPLETED" for s in states.values()), f"forest: 5 units and the merge completed: {states}")
    print(f"forest submission: {time.monotonic() - t0:.1f} s", flush=True)
    same = run(lblight, "compare", "--exact", work / "forest-single", work / "forest-sub" / "bake", expect=None)
    print(same.stdout, end="")
    check(same.returncode == 0, "the forest's merged bake equals its one-machine bake bit for bit")

    # One lattice across 2 MPI ranks inside the allocation (srun --mpi=pmix, --backend mpi): the same
    # bits as the one-machine bake of the forest's B06 (skipped where lblight was built without MPI).
    probe = run(lblight, "bake", other_scene, "--backend", "mpi", "--solutions", "6", "-o", work / "mpi-probe",
                expect=None)
    if "built without MPI" in probe.stderr:
        print("skipped: srun --mpi=pmix (lblight was built without MPI)", flush=True)
    else:
        r = run("srun", "--mpi=pmix", "-n", "2", "-c", "1", "--time", "5", lblight, "bake", forest, *forest_args,
                "--backend", "mpi", "--threads", "1", "-o", work / "forest-srun", expect=None)
        check(r.returncode == 0 and "MPI, 2 rank(s)" in r.stderr,
              "srun --mpi=pmix -n 2 bakes the forest with --backend mpi: " + r.stderr[-300:])
        same = run(lblight, "compare", "--exact", work / "forest-single", work / "forest-srun", expect=None)
        diffs = [l for l in same.stdout.splitlines() if l.startswith("differs:")]
        check(diffs == ["differs: manifest /backend/name (replace)"],
              "2 MPI ranks under srun equal the one-machine bake bit for bit but the backend's name: " +
              "; ".join(diffs[:5]))

    # A partial of another scene is refused by name, and nothing is written.
    run(lblight, "-q", "bake", other_scene, "--only", "tree", "-o", work / "foreign")
    for args in (["--scene", scene], []):
        r = run(lblight, "merge", *args, work / "sub" / "parts" / "cumulus", work / "foreign", "-o", work / "mixed",
                expect=2)
        check(f"refused part {work / 'foreign'}" in r.stderr and "foreign" in r.stderr and not (work / "mixed").exists(),
              "the merge refuses a partial of another scene" + (" (--scene)" if args else "") + ": " +
              r.stderr.strip().splitlines()[-1])


if __name__ == "__main__":
    sys.exit(main())

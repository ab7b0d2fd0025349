#!/usr/bin/env python3
"""One lattice across MPI ranks (`--backend mpi`, docs/scale-out.md): a plant on a ground, all 19
solutions with iterations auto (every halo direction crosses the slab faces, and the stopping rule
sees the gathered residuals), baked with mpirun on 1, 2 and 3 ranks (3: a middle rank exchanging
with both neighbours) must equal each other bit for bit (`lblight compare --exact`) and the CPU
backend except for the backend's name; the halo exchange time is reported; too many ranks and a
Krylov method are refused. Skipped (exit 77, saying why) where lblight was built without MPI or
mpirun is missing.

usage: check_mpi.py LBLIGHT WORK_DIR"""
import shutil
import subprocess
import sys
from pathlib import Path

SKIP = 77
lblight, work = Path(sys.argv[1]).resolve(), Path(sys.argv[2]).resolve()
failures = []


def check(ok, what):
    print(("ok: " if ok else "FAIL: ") + what, flush=True)
    if not ok:
        failures.append(what)


def run(*args):
    return subprocess.run([str(a) for a in args], capture_output=True, text=True, cwd=work)


mpirun = shutil.which("mpirun")
if not mpirun:
    print("SKIPPED: mpirun is not installed (scripts/setup-debian.sh installs Debian's openmpi-bin)")
    sys.exit(SKIP)
shutil.rmtree(work, ignore_errors=True)
work.mkdir(parents=True)
(work / "plant.json").write_text("""{
 "version": 1, "name": "plant",
 "models": [{"name": "m", "density": {"type": "procedural", "shape": "plant", "resolution": 14, "seed": 3},
             "material": "leaf", "wood_material": "bark"}],
 "lighting": {"mode": "base", "solutions": "all"},
 "solver": {"iterations": "auto", "tolerance": 1e-3},
 "ground": {"albedo": [0.2, 0.3, 0.4]}
}
""")
probe = run(lblight, "bake", "plant.json", "-o", "probe", "--backend", "mpi", "--solutions", "6", "-q")
if probe.returncode != 0 and "built without MPI" in probe.stderr:
    print("SKIPPED: " + probe.stderr.strip().splitlines()[-1])
    sys.exit(SKIP)
check(probe.returncode == 0, "a bake with --backend mpi outside mpirun runs as one rank: " + probe.stderr[-300:])

def rank_folders():
    return sorted(p.name for p in Path("/tmp").glob("lblight-rank-output-*"))


before = rank_folders()
mpi = [mpirun, "--allow-run-as-root", "--oversubscribe", "-np"]
cpu = run(lblight, "bake", "plant.json", "-o", "cpu", "--backend", "cpu", "-q")
check(cpu.returncode == 0, "CPU bake: " + cpu.stderr[-300:])
for n in (1, 2, 3):
    r = run(*mpi, n, lblight, "bake", "plant.json", "-o", f"mpi{n}", "--backend", "mpi", "--threads", "1")
    check(r.returncode == 0, f"{n} rank(s) bake: " + r.stderr[-500:])
    halo = [l for l in r.stderr.splitlines() if "halo exchange" in l]
    check(len(halo) > 0 and f"MPI: {n} rank(s)" in halo[0], f"{n} rank(s): the halo exchange time is reported: " +
          (halo[0] if halo else "(no line)"))
    if halo:
        print("  " + halo[0].split("info: ")[-1])
    check(rank_folders() == before, f"{n} rank(s): ranks other than 0 leave no output behind")
for n in (2, 3):
    r = run(lblight, "compare", "--exact", "mpi1", f"mpi{n}")
    check(r.returncode == 0, f"{n} ranks equal 1 rank bit for bit: " + (r.stdout + r.stderr)[-600:])
r = run(lblight, "compare", "--exact", "cpu", "mpi2")
diffs = [l for l in r.stdout.splitlines() if l.startswith("differs:")]
check(diffs == ["differs: manifest /backend/name (replace)"],
      "2 ranks equal the CPU backend bit for bit (grids, .lbh, manifest but the backend's name): " + "; ".join(diffs[:5]))

r = run(*mpi, 30, lblight, "bake", "plant.json", "-o", "many", "--backend", "mpi", "--threads", "1", "--solutions", "6")
check(r.returncode != 0 and "each rank needs at least one" in r.stderr and not (work / "many").exists(),
      "more ranks than interior layers is refused, naming the limit")
r = run(lblight, "bake", "plant.json", "-o", "krylov", "--backend", "mpi", "--method", "bicgstab")
check(r.returncode == 2 and "plain" in r.stderr and not (work / "krylov").exists(), "a Krylov method is refused")

r = run(lblight, "report", "plant.json", "-o", "rep", "--backend", "mpi", "--solutions", "6")
check(r.returncode == 2 and "lblight bake" in r.stderr and not (work / "rep").exists(),
      "report refuses --backend mpi (each rank would write it), naming bake")

if failures:
    print(f"{len(failures)} check(s) failed")
    sys.exit(1)
print("all MPI checks passed")

"""A mixed cluster: `cellphys run --mpi` in MPMD form with the dispatcher built for one SIMD
path and the compute nodes for another ends on the in-process state hash, both ways round
(docs/determinism.md).

usage: test_mpi_mixed.py CELLPHYS MPIRUN OTHER_BUILD...   (run by CTest)

OTHER_BUILD are the cellphys executables of other presets' build trees (release, scalar,
avx2); those not built are left out, and the test is skipped (exit 77) if none is built.
"""
import json
import os
import subprocess
import sys
import tempfile

EXE, MPIRUN, OTHERS = sys.argv[1], sys.argv[2], sys.argv[3:]
MPI = [MPIRUN, "--oversubscribe", "--allow-run-as-root", "--mca", "btl", "self,vader,tcp",
       "--mca", "btl_vader_single_copy_mechanism", "none"]
ARGS = ["--duration", "0.5"]
SCENES = ("pile65", "chain_ratio")


def run(cmd, stats):
    """Runs cmd (whose rank 0 writes `stats`) and returns (state hash, SIMD path) from it."""
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} exited {p.returncode}\n{p.stdout}\n{p.stderr}")
    with open(stats) as f:
        s = json.load(f)
    return s["state_hash"], s["simd_path"]


def main():
    others = [o for o in OTHERS if os.path.isfile(o) and os.path.realpath(o) != os.path.realpath(EXE)]
    if not others:
        print("skipped: no other preset's cellphys is built (scripts/build release or scalar first)")
        return 77
    failures = 0
    with tempfile.TemporaryDirectory() as d:
        stats = os.path.join(d, "stats.json")
        for scene in SCENES:
            ref, here = run([EXE, "run", scene, *ARGS, "--stats", stats], stats)
            for other in others:
                alone, there = run([other, "run", scene, *ARGS, "--stats", stats], stats)
                paths = {EXE: here, other: there}
                results = [(f"{there} in-process", alone)]
                for dispatcher, node in ((EXE, other), (other, EXE)):
                    cmd = [*MPI, "-np", "1", dispatcher, "run", scene, *ARGS, "--mpi", "--stats", stats,
                           ":", "-np", "2", node, "run", scene, *ARGS, "--mpi"]
                    results.append((f"dispatcher {paths[dispatcher]}, nodes {paths[node]}", run(cmd, stats)[0]))
                for what, got in results:
                    ok = got == ref
                    failures += not ok
                    print(f"{scene}: {what}: {got} {'==' if ok else '!='} {here} in-process {ref}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())

"""scripts/mpi-survive under mpirun on loopback: a compute node SIGKILLed mid-run (Open MPI then
ends the whole job) is survived by restarting from the last checkpoint with one node fewer, and
the run ends on the uninterrupted run's state hash.

usage: test_mpi_survive.py CELLPHYS MPIRUN LAUNCHER  (run by CTest; exit 77 without mpirun)
"""
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import unittest

EXE, MPIRUN, LAUNCHER = sys.argv[1], sys.argv[2], sys.argv[3]
MPI = (f"{MPIRUN} --oversubscribe --allow-run-as-root --mca btl self,vader,tcp"
       " --mca btl_vader_single_copy_mechanism none")
TIMEOUT = 120
STEPS, EVERY = 300, 10
# world1000's last node has been sent 15,000 islands after about 35 of 300 steps with 3 ranks,
# and its only node 30,000 after about 30 with 2: past a checkpoint, well before the end.
KILL = {3: 15000, 2: 30000}


def survive(d, ranks, *extra):
    cmd = [sys.executable, LAUNCHER, "--cellphys", EXE, "--mpirun", MPI, "-np", str(ranks),
           "--checkpoint", os.path.join(d, "ck.snap"), "--checkpoint-every", str(EVERY), "--steps", str(STEPS),
           "--stats", os.path.join(d, "stats.json"), "world1000", *extra]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT)


class MpiSurvive(unittest.TestCase):
    reference = None

    @classmethod
    def setUpClass(cls):
        with tempfile.TemporaryDirectory() as d:
            stats = os.path.join(d, "ref.json")
            subprocess.run([EXE, "run", "world1000", "--steps", str(STEPS), "--stats", stats], check=True,
                           capture_output=True, timeout=TIMEOUT)
            with open(stats) as f:
                cls.reference = json.load(f)["state_hash"]

    def killed_and_restarted(self, ranks, nodes_after):
        with tempfile.TemporaryDirectory() as d:
            p = survive(d, ranks, "--", "--mpi-fault", f"kill:{KILL[ranks]}")
            out = p.stdout + p.stderr
            self.assertEqual(p.returncode, 0, out)
            # the node really died of SIGKILL, as mpirun saw it, and the launcher said so
            self.assertRegex(p.stderr, rf"process rank {ranks - 1} with PID \d+ on node \S+ exited on signal 9")
            died = re.search(rf"compute node rank {ranks - 1} died \(signal 9\); restarting from the checkpoint "
                             rf"at step (\d+) of {STEPS}, {re.escape(nodes_after)}", p.stdout)
            self.assertIsNotNone(died, out)
            step = int(died.group(1))
            self.assertGreater(step, 0)
            self.assertLess(step, STEPS)
            self.assertEqual(step % EVERY, 0)
            self.assertRegex(p.stdout, r"restart 1 took \d+\.\d+ s")
            self.assertIn(f"done: step {STEPS} of {STEPS}, state hash {self.reference}, 1 restart", p.stdout)
            with open(os.path.join(d, "stats.json")) as f:
                stats = json.load(f)
            self.assertEqual(stats["state_hash"], self.reference)
            self.assertEqual(stats["step_counter"], STEPS)
            self.assertEqual(stats["steps"], STEPS - step)  # the restart ran only what was left
            self.assertEqual(sorted(os.listdir(d)), ["ck.snap", "stats.json"])  # no temporaries left
            return stats

    def test_killed_node_of_two_restarts_on_one(self):
        self.assertEqual(self.killed_and_restarted(3, "1 compute node")["runner"], "mpi")

    def test_killed_last_node_finishes_in_process(self):
        self.assertEqual(self.killed_and_restarted(2, "in-process (no node left)")["runner"], "threads")

    def test_uninterrupted_run_is_not_restarted(self):
        with tempfile.TemporaryDirectory() as d:
            p = survive(d, 3)
            self.assertEqual(p.returncode, 0, p.stdout + p.stderr)
            self.assertIn(f"done: step {STEPS} of {STEPS}, state hash {self.reference}, 0 restarts", p.stdout)

    def test_bad_input_is_refused_before_any_job(self):
        with tempfile.TemporaryDirectory() as d:
            for args, message in (
                    (["--checkpoint-every", "0"], "--checkpoint-every takes a whole number greater than 0, got '0'"),
                    (["--checkpoint-every", "-5"], "--checkpoint-every takes a whole number greater than 0, got '-5'"),
                    (["-np", "1"], "-np needs at least 2 ranks (a dispatcher and a compute node), got 1"),
                    (["--checkpoint", os.path.join(d, "missing", "ck.snap")], "cannot write there: No such file"),
                    (["--checkpoint", d], "is a directory")):
                with self.subTest(args=args):
                    cmd = [sys.executable, LAUNCHER, "--cellphys", EXE, "--mpirun", MPI, "-np", "3", "--checkpoint",
                           os.path.join(d, "ck.snap"), "--checkpoint-every", "10", "--steps", "30", *args, "world1000"]
                    p = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT)
                    self.assertEqual(p.returncode, 2, p.stdout + p.stderr)
                    self.assertIn(message, p.stderr)
                    self.assertNotIn("job 1", p.stdout)

    def test_unwritable_snapshot_fails_before_the_first_step(self):
        # cellphys itself: an unwritable --save-snapshot is found at the start, not after the run
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "missing", "ck.snap")
            p = subprocess.run([EXE, "run", "world1000", "--steps", "1000000", "--save-snapshot", path,
                                "--snapshot-every", "10"], capture_output=True, text=True, timeout=TIMEOUT)
            self.assertEqual(p.returncode, 1, p.stdout + p.stderr)
            self.assertIn(f"{path}: cannot create a file next to it", p.stderr)


if __name__ == "__main__":
    if not shutil.which(MPIRUN):
        print(f"test_mpi_survive: no mpirun ({MPIRUN}): skipped")
        sys.exit(77)
    unittest.main(argv=sys.argv[:1], verbosity=2)

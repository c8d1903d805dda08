"""`cellphys run --mpi` under mpirun on loopback: the same bits as the in-process run, the
reference design's wire tables on the wire in one batch per node and wave, damaged replies recomputed,
silent nodes dropped, and a hung node ending the job one deadline after the run.

usage: test_mpi_run.py CELLPHYS MPIRUN  (run by CTest)
"""
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import unittest

EXE, MPIRUN = sys.argv[1], sys.argv[2]
MPI = [MPIRUN, "--oversubscribe", "--allow-run-as-root", "--mca", "btl", "self,vader,tcp",
       "--mca", "btl_vader_single_copy_mechanism", "none"]
TIMEOUT = 120


def run(args, ranks=None):
    with tempfile.TemporaryDirectory() as d:
        stats = os.path.join(d, "stats.json")
        cmd = ([*MPI, "-np", str(ranks)] if ranks else []) + [EXE, "run", *args, "--stats", stats]
        if ranks:
            cmd.append("--mpi")
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=TIMEOUT)
        if p.returncode != 0:
            raise AssertionError(f"{' '.join(cmd)} exited {p.returncode}\n{p.stdout}\n{p.stderr}")
        with open(stats) as f:
            return json.load(f)


class MpiRun(unittest.TestCase):
    reference = {}

    def local(self, scene):
        if scene not in self.reference:
            self.reference[scene] = run([scene, "--duration", "1"])
        return self.reference[scene]

    def test_pile65_and_world1000_bit_for_bit(self):
        for scene in ("pile65", "world1000"):
            with self.subTest(scene=scene):
                ref = self.local(scene)
                got = run([scene, "--duration", "1"], ranks=3)
                self.assertEqual(got["runner"], "mpi")
                self.assertEqual(got["state_hash"], ref["state_hash"])
                self.assertEqual(got["steps"], ref["steps"])
                t = got["transport"]
                self.assertEqual(t["recomputed_islands"], 0)
                # per-body figures are bytes times 1 / bodies in double: 13 floats a body to rounding
                # (one byte more or less over the run is > 1e-6 a body)
                self.assertAlmostEqual(t["table_from_nodes_per_body"], 52.0, places=9)
                self.assertAlmostEqual(t["table_to_nodes_compressed_per_body"] - t["shared_per_body"], 100.0, places=9)
                # one batch a node and wave each way: a 32-byte batch header per message, and per
                # island a 16-byte job record out and a 48-byte result record back
                batches = t["messages"] / 2 / t["island_bodies"]  # per body
                over_out = t["bytes_to_nodes_per_body"] - t["table_to_nodes_compressed_per_body"] - 32 * batches
                over_back = t["bytes_from_nodes_per_body"] - 52.0 - 32 * batches
                islands = over_back / 48  # per body
                self.assertGreater(islands, 0)
                self.assertAlmostEqual(over_out, 16 * islands, places=6)
                if scene == "world1000":  # many small islands: many to a message
                    self.assertGreater(islands / batches, 10)
                if scene == "world1000":  # hulls: a dictionary reference beats geometry
                    self.assertLess(t["table_to_nodes_compressed_per_body"], t["table_to_nodes_per_body"])

    def test_damaged_reply_is_recomputed(self):
        ref = self.local("world1000")
        got = run(["world1000", "--duration", "1", "--mpi-fault", "corrupt:7"], ranks=3)
        self.assertEqual(got["state_hash"], ref["state_hash"])
        self.assertEqual(got["transport"]["bad_messages"], 1)
        self.assertEqual(got["transport"]["recomputed_islands"], 1)

    def test_silent_node_is_dropped_and_its_islands_reassigned(self):
        ref = self.local("world1000")
        # The deadline must exceed a healthy node's longest batch: under the sanitizers, with three
        # ranks on two cores, world1000's first batches take longer than 300 ms.
        got = run(["world1000", "--duration", "1", "--mpi-fault", "silent:30", "--mpi-deadline", "2000"], ranks=3)
        self.assertEqual(got["state_hash"], ref["state_hash"])
        self.assertEqual(got["transport"]["dropped_nodes"], 1)
        self.assertGreater(got["transport"]["reassigned_islands"], 0)

    def test_hung_node_at_exit_ends_the_job_after_the_deadline(self):
        # A node that stops reading anything (a hung process) is dropped within the run; at the
        # end it cannot say goodbye, and MPI_Finalize would wait for it forever: the dispatcher
        # waits one deadline, names the rank and aborts the job with exit code 3, its outputs
        # already written.
        #
        # What happens after the abort is the launcher's: Open MPI 4.1's mpirun, once every rank
        # has ended, now and then deadlocks in its own PMIx server's finalize, or crashes there.
        # So the test waits for mpirun or, failing that, for every rank to have ended; a launcher
        # still running 10 s after its last rank ended is killed and its exit code not judged.
        ref = self.local("world1000")
        with tempfile.TemporaryDirectory() as d:
            stats = os.path.join(d, "stats.json")
            cmd = [*MPI, "-np", "3", EXE, "run", "world1000", "--duration", "1", "--mpi", "--mpi-fault", "hang:30",
                   "--mpi-deadline", "2000", "--stats", stats]
            with open(os.path.join(d, "out"), "w+") as out, open(os.path.join(d, "err"), "w+") as err:
                p = subprocess.Popen(cmd, stdout=out, stderr=err, text=True)
                launcher_stuck = wait_for_job(p)
                out.seek(0)
                err.seek(0)
                output, errors = out.read(), err.read()
            if not launcher_stuck:
                self.assertIn(p.returncode, (3, -signal.SIGSEGV, -signal.SIGABRT), output + errors)
            # (Open MPI's own report of the abort is not checked: its launcher sometimes fails to
            # print it, "ORTE_ERROR_LOG: Out of resource in show_help.c".)
            self.assertIn("compute node rank 2 did not stop within 2000 ms", errors, output + errors)
            with open(stats) as f:
                got = json.load(f)
        self.assertEqual(got["state_hash"], ref["state_hash"])
        self.assertEqual(got["transport"]["dropped_nodes"], 1)


def child_states(pid):
    """The process states (R, S, Z, ...) of pid's children, read from /proc."""
    states = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/stat") as f:
                stat = f.read()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()  # after "pid (command) "
        if int(fields[1]) == pid:
            states.append(fields[0])
    return states


def wait_for_job(p, grace=10.0):
    """Waits for mpirun p to exit; True when instead it outlived all its ranks by `grace` s
    (it is then killed). Fails the test when the job is still running after TIMEOUT."""
    start = time.monotonic()
    saw_rank, ranks_ended_at = False, None
    while p.poll() is None:
        now = time.monotonic()
        if now - start > TIMEOUT:
            p.kill()
            p.wait()
            raise AssertionError(f"the job still ran after {TIMEOUT} s")
        live = [s for s in child_states(p.pid) if s != "Z"]
        saw_rank = saw_rank or bool(live)
        if saw_rank and not live:
            ranks_ended_at = ranks_ended_at or now
            if now - ranks_ended_at > grace:
                p.kill()
                p.wait()
                return True
        else:
            ranks_ended_at = None
        time.sleep(0.2)
    return False


if __name__ == "__main__":
    unittest.main(argv=sys.argv[:1], verbosity=2)

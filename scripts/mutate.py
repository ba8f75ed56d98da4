#!/usr/bin/env python3
"""Mutation check of the safety layer and the failure paths: do the tests notice a realistic bug?

Each mutant is one small bug someone could plausibly write (a bound dropped, a comparison flipped, a flush lost,
a unit confused) in one of the modules that keep the arm safe or end an episode cleanly. The script copies the
checkout into a temporary directory (the working tree is never touched), runs the tests of every module once
unmutated (they must pass), then applies one mutant at a time to the copy and runs that module's tests: a failing
test kills the mutant, a green run means it survived. Run on demand, not in the test suite (about 20 minutes):

    .venv/bin/python scripts/mutate.py              # every mutant, a line per mutant, the score last
    .venv/bin/python scripts/mutate.py safety damiao  # the mutants whose names start with these
    .venv/bin/python scripts/mutate.py --list       # names and bugs, nothing run
    .venv/bin/python scripts/mutate.py --json       # the results as JSON

Exit code: 0 every mutant killed, 1 some survived, 2 the check could not run (a mutant no longer matches its
module's code: update its text here; or the unmutated tests fail). docs/reliability.md has the last score and
why each survivor is acceptable.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SKIP = {".git", ".venv", "runs", ".hypothesis", ".pytest_cache", ".ruff_cache", "__pycache__", "axisloop.egg-info"}
TIMEOUT_S = 900  # a mutant that makes a test hang counts as killed once this passes

SAFETY_TESTS = ("tests/test_safety.py", "tests/test_safety_limits.py", "tests/test_sim_arm.py", "tests/test_motion.py",
                "tests/test_can_arm.py")
CODEC_TESTS = ("tests/test_damiao.py", "tests/test_damiao_codec.py", "tests/test_motor_channels.py")
CHANNEL_TESTS = ("tests/test_motor_channels.py", "tests/test_damiao_codec.py", "tests/test_safety_limits.py",
                 "tests/test_can_arm.py")
WRITER_TESTS = ("tests/test_frames_dir.py", "tests/test_durability.py")
FORCE_TESTS = ("tests/test_force_limits.py", "tests/test_force_pulling.py")
EPISODE_TESTS = ("tests/test_failure_paths.py",
                 "tests/test_control_episode.py::test_locked_drawer_ends_blocked_and_safe",
                 "tests/test_control_episode.py::test_slipping_grasp_regrasps_once_then_fails_clearly",
                 "tests/test_control_episode.py::test_a_slip_is_recovered_by_finding_the_handle_again",
                 "tests/test_control_episode.py::test_lost_tracking_stops_safely")


@dataclass(frozen=True)
class Mutant:
    """Replace `old` (exactly one occurrence) by `new` in `path`; `tests` are the pytest targets that must notice."""

    name: str
    bug: str
    path: str
    old: str
    new: str
    tests: tuple[str, ...]


def _safety(name: str, bug: str, old: str, new: str) -> Mutant:
    return Mutant(f"safety.{name}", bug, "drivers/arm/safety.py", old, new, SAFETY_TESTS)


def _codec(name: str, bug: str, old: str, new: str) -> Mutant:
    return Mutant(f"damiao.{name}", bug, "drivers/arm/damiao/codec.py", old, new, CODEC_TESTS)


def _channel(name: str, bug: str, old: str, new: str) -> Mutant:
    return Mutant(f"channels.{name}", bug, "drivers/arm/motor_channels.py", old, new, CHANNEL_TESTS)


def _writer(name: str, bug: str, old: str, new: str) -> Mutant:
    return Mutant(f"writer.{name}", bug, "drivers/camera/frames_dir.py", old, new, WRITER_TESTS)


def _force(name: str, bug: str, old: str, new: str) -> Mutant:
    return Mutant(f"force.{name}", bug, "drivers/arm/motion.py", old, new, FORCE_TESTS)


def _episode(module: str, name: str, bug: str, old: str, new: str) -> Mutant:
    return Mutant(f"{module}.{name}", bug, f"deploy/control/{module}.py", old, new, EPISODE_TESTS)


ACCEL = "_worst(np.abs(ddq) - lim.a_max * (1 + RELATIVE_SLACK))"
WORKSPACE = "outside = ~np.isfinite(p) | (p < lim.workspace_min) | (p > lim.workspace_max)"
Q_MAX, Q_MIN = "_worst(q - lim.q_max - q_tol)", "_worst(lim.q_min - q - q_tol)"
STEP = "step = np.where(np.abs(from_measured) < np.abs(step), from_measured, step)"
CLAMP = "x = min(max(float(x), lo), hi) if math.isfinite(x) else 0.0"
FINITE = "if not all(math.isfinite(v) for v in (q, dq, kp, kd, tau)):"
LINE_SYNC = "        self._jsonl.flush()\n        os.fsync(self._jsonl.fileno())\n"
DIR_SYNC = ("        for sub in written:  # the PNGs' names must be on disk before the line that lists them\n"
            "            self._sync_directory(self.path / sub)\n")
RECORD = """
        record: dict = {"index": self._count, "t": float(frame.t)}
        if joint_positions is not None:
            record["joint_positions"] = [float(v) for v in np.ravel(joint_positions)]
        if ee_pose is not None:
            record["ee_pose"] = _pose_list(ee_pose, "ee_pose")
        if first:
            record["first"] = True
        if grasped is not None:
            record["grasped"] = bool(grasped)
        pose = frame.T_base_camera  # a camera that moves (eye-in-hand): its pose per frame, where not meta.json's
        if pose is not None and not (self._pose is not None and np.allclose(pose, self._pose, rtol=0, atol=1e-9)):
            record["T_base_camera"] = _pose_list(pose, "T_base_camera")
        self._jsonl.write(json.dumps(record) + "\\n")
"""
GRASP = "if not MIN_GRASP_WIDTH_M < width < open_width - OPEN_MARGIN_M:"
FORCE_STOP = "if limit is not None and (force > limit or stuck):"
BOUNDS = "slow_from, halt_at = self.c.slow_from * limit, self.c.halt_at * limit"
STILL = "self.still_s = self.still_s + self.arm.control_period_s if self.scale < STALL_SCALE else 0.0"

MUTANTS = [
    _safety("accel-braking-unchecked", "acceleration checked only when speeding up", ACCEL,
            "_worst(ddq * np.sign(dq) - lim.a_max * (1 + RELATIVE_SLACK))"),
    _safety("accel-from-rest-unchecked", "no acceleration check when the previous velocity is zero",
            "if dq_cmd is not None and dq_prev_cmd is not None:",
            "if dq_cmd is not None and dq_prev_cmd is not None and np.any(dq_prev_cmd):"),
    _safety("accel-times-dt", "acceleration computed as dv * dt", "ddq = (dq - self._vector(\"previous velocity\", "
            "dq_prev_cmd)) / dt", "ddq = (dq - self._vector(\"previous velocity\", dq_prev_cmd)) * dt"),
    _safety("accel-against-velocity-limit", "acceleration compared with the velocity limit", ACCEL,
            "_worst(np.abs(ddq) - lim.v_max * (1 + RELATIVE_SLACK))"),
    _safety("workspace-max-dropped", "the workspace box's upper bound dropped", WORKSPACE,
            "outside = ~np.isfinite(p) | (p < lim.workspace_min)"),
    _safety("workspace-min-dropped", "the workspace box's lower bound dropped", WORKSPACE,
            "outside = ~np.isfinite(p) | (p > lim.workspace_max)"),
    _safety("workspace-nan-inside", "a NaN tool position counts as inside", WORKSPACE,
            "outside = (p < lim.workspace_min) | (p > lim.workspace_max)"),
    _safety("workspace-wrong-axis", "the message names the wrong axis", "axis = \"xyz\"[int(np.argmax(outside))]",
            "axis = \"xyz\"[int(np.argmin(outside))]"),
    _safety("q-max-checks-q-min", "copy-paste: both position checks test the lower limit", Q_MAX, Q_MIN),
    _safety("q-min-checks-q-max", "copy-paste: both position checks test the upper limit", Q_MIN, Q_MAX),
    _safety("q-tolerance-sign", "the rounding slack subtracted from the range", Q_MAX,
            "_worst(q - lim.q_max + q_tol)"),
    _safety("slack-one-percent", "a 'small' slack of 1 %", "RELATIVE_SLACK = 1e-6", "RELATIVE_SLACK = 1e-2"),
    _safety("velocity-sign", "negative velocities unchecked", "_worst(np.abs(dq) - v_max)", "_worst(dq - v_max)"),
    _safety("jump-sign", "backward jumps unchecked", "_worst(np.abs(step) - max_step)", "_worst(step - max_step)"),
    _safety("jump-without-dt", "the jump limit forgets the period", "max_step = v_max * dt + lim.jump_tolerance_rad",
            "max_step = v_max + lim.jump_tolerance_rad"),
    _safety("step-from-farther", "a step measured from the farther of command and arm", STEP,
            "step = np.where(np.abs(from_measured) > np.abs(step), from_measured, step)"),
    _safety("step-from-measured-only", "a step measured from the arm only", STEP, "step = from_measured"),
    _safety("non-finite-isnan", "inputs checked with isnan (inf passes)", "np.where(np.isfinite(x), -1.0, 1.0)",
            "np.where(np.isnan(x), 1.0, -1.0)"),
    _safety("refuse-at-limit", "a value exactly at its limit refused", "if np.max(excess) > 0",
            "if np.max(excess) >= 0"),
    _safety("first-not-worst", "names the first joint past a limit, not the farthest", "int(np.argmax(excess))",
            "int(np.argmax(excess > 0))"),
    _safety("dt-nan-passes", "a NaN control period passes", "if not (np.isfinite(dt) and dt > 0):", "if dt <= 0:"),
    _safety("limits-nan-pass", "a NaN joint limit accepted", "if not np.all(self.q_min < self.q_max):",
            "if np.any(self.q_min >= self.q_max):"),
    _codec("non-finite-to-minimum", "a NaN command encoded as the range minimum", CLAMP,
           "x = min(max(float(x), lo), hi) if math.isfinite(x) else lo"),
    _codec("non-finite-to-centre", "a NaN command encoded as the range centre (kp 250)", CLAMP,
           "x = min(max(float(x), lo), hi) if math.isfinite(x) else 0.5 * (lo + hi)"),
    _codec("clamp-upper-dropped", "values above the range overflow their bits", CLAMP,
           "x = max(float(x), lo) if math.isfinite(x) else 0.0"),
    _codec("clamp-lower-dropped", "values below the range wrap around", CLAMP,
           "x = min(float(x), hi) if math.isfinite(x) else 0.0"),
    _codec("truncate", "truncation instead of rounding", "return int(round((x - lo) / (hi - lo) * ((1 << bits) - 1)))",
           "return int((x - lo) / (hi - lo) * ((1 << bits) - 1))"),
    _codec("tau-nibble", "the torque's high nibble shifted wrongly", "kdi >> 4, ((kdi & 0xF) << 4) | (ti >> 8)",
           "kdi >> 4, ((kdi & 0xF) << 4) | (ti >> 4)"),
    _codec("special-any-last-byte", "any FF x7 frame counts as a special command",
           "data[:7] == b\"\\xff\" * 7 and data[7] in {int(s) for s in Special}", "data[:7] == b\"\\xff\" * 7"),
    _codec("temperature-wraps", "temperatures wrap instead of clamping", "min(max(int(t_mos_c), 0), 255)",
           "int(t_mos_c) & 0xFF"),
    _channel("gains-not-checked", "the non-finite refusal forgets the gains", FINITE,
             "if not all(math.isfinite(v) for v in (q, dq, tau)):"),
    _channel("position-only-checked", "the non-finite refusal checks the position only", FINITE,
             "if not all(math.isfinite(v) for v in (q,)):"),
    _channel("pmax-clamp-dropped", "motor positions not kept inside PMAX",
             "q_m = min(max(float(q_m), -PMAX_MARGIN * lim.p_max), PMAX_MARGIN * lim.p_max)", "q_m = float(q_m)"),
    _channel("torque-sign", "negative torques unchecked", "tau = abs(fb.tau)", "tau = fb.tau"),
    _channel("torque-margin-dropped", "the torque margin forgotten (false stops)",
             "limit = tau_max * watchdog.torque_margin", "limit = tau_max"),
    _channel("watchdog-in-ms", "the feedback timeout read as milliseconds", "if age_s > timeout:",
             "if age_s > timeout * 1e3:"),
    _channel("only-over-current", "only over-current counts as a fault", "if fb.status.is_fault:",
             "if fb.status == Status.OVER_CURRENT:"),
    _channel("disabled-unnoticed", "a motor that disabled itself goes unnoticed",
             "if fb.status == Status.DISABLED:", "if fb.status == Status.DISABLED and tau_max is None:"),
    _writer("line-neither-flushed-nor-synced", "the frame line left in Python's buffer", LINE_SYNC, ""),
    _writer("line-not-flushed", "the frame line fsynced but never flushed", LINE_SYNC,
            "        os.fsync(self._jsonl.fileno())\n"),
    _writer("line-not-synced", "the frame line flushed but not fsynced", LINE_SYNC, "        self._jsonl.flush()\n"),
    _writer("images-not-synced", "PNGs written without fsync",
            "        f.write(data)\n        f.flush()\n        os.fsync(f.fileno())\n", "        f.write(data)\n"),
    _writer("directories-not-synced", "the PNGs' directory entries not synced", DIR_SYNC, ""),
    _writer("line-before-directories", "the line synced before the PNGs' names", DIR_SYNC + RECORD + LINE_SYNC,
            RECORD.lstrip("\n") + LINE_SYNC + DIR_SYNC),
    _force("limit-doubled", "the force limit compared with twice its value", FORCE_STOP,
           "if limit is not None and (force > 2 * limit or stuck):"),
    _force("stall-unchecked", "a pull held still never ends (only the limit stops it)", FORCE_STOP,
           "if limit is not None and force > limit:"),
    _force("slow-counts-as-still", "a slowed pull counted as held still", STILL,
           "self.still_s = self.still_s + self.arm.control_period_s if self.scale < 1.0 else 0.0"),
    _force("halt-at-limit", "the halt fraction dropped: the pull halts at the limit, not at 85 % of it", BOUNDS,
           "slow_from, halt_at = self.c.slow_from * limit, limit"),
    _force("no-slow-down", "no slowing past half the limit: full speed up to the halt", BOUNDS,
           "slow_from, halt_at = self.c.halt_at * limit, self.c.halt_at * limit"),
    _force("no-back-off", "no backing off above the halt: the pull only stops",
           "max(halt_at - slow_from, 1e-9), -1.0, 1.0))", "max(halt_at - slow_from, 1e-9), 0.0, 1.0))"),
    _force("bias-ignored", "the force held before the pull (the grasp's squeeze) counted as the pull's",
           "self.bias = self.wrench.force  #", "self.bias = np.zeros(3)  #"),
    _force("peak-is-last", "the peak force reported is the last one",
           "self.peak_force_n = max(self.peak_force_n, self.pull_n)", "self.peak_force_n = self.pull_n"),
    _episode("stages", "grasp-lower-bound-dropped", "a gripper closed on air counts as a grasp", GRASP,
             "if not width < open_width - OPEN_MARGIN_M:"),
    _episode("stages", "grasp-upper-bound-dropped", "a gripper that did not close counts as a grasp", GRASP,
             "if not MIN_GRASP_WIDTH_M < width:"),
    _episode("stages", "regrasp-not-recorded", "a re-grasp not recorded: slips re-grasp forever",
             "        episode.state.regrasped = True\n", ""),
    _episode("stages", "slip-unchecked", "a slip after a pull not noticed", "    if not episode.gripping():\n",
             "    if False:\n"),
    _episode("stages", "blocked-ignored", "a blocked pull not ending the episode",
             "elif result.outcome is Outcome.BLOCKED:", "elif result.outcome is Outcome.STOPPED:"),
    _episode("stages", "max-steps-off-by-one", "one step more than allowed", "if state.steps >= cfg.max_steps:",
             "if state.steps > cfg.max_steps:"),
    _episode("stages", "timeout-in-minutes", "the time limit read as minutes", "if episode.now() > cfg.timeout_s:",
             "if episode.now() > cfg.timeout_s * 60:"),
    _episode("context", "min-grasp-zero", "any width above 0 counts as holding", "MIN_GRASP_WIDTH_M = 0.003",
             "MIN_GRASP_WIDTH_M = 0.0"),
    _episode("context", "pull-ignores-slip", "a pull goes on after the handle slipped out",
             "return held and self.now()", "return True and self.now()"),
    _episode("observer", "mask-check-dropped", "a lost object not ending the episode",
             "if np.count_nonzero(mask) < self._config.opening.min_mask_fraction * self._mask_pixels:",
             "if False:"),
]


def copy_checkout(destination: Path) -> None:
    """The checkout without its environment, caches and runs."""
    shutil.copytree(ROOT, destination, ignore=lambda _d, names: [n for n in names if n in SKIP])


def run_tests(tree: Path, targets: tuple[str, ...]) -> tuple[bool, float, str]:
    """(passed, seconds, what failed) of pytest on `targets` in `tree`, stopping at the first failure."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "PYTHONPATH": str(tree), "PYTHONDONTWRITEBYTECODE": "1"}
    command = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", *targets]
    start = time.perf_counter()
    try:
        out = subprocess.run(command, cwd=tree, env=env, capture_output=True, text=True, timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return False, time.perf_counter() - start, f"timed out after {TIMEOUT_S} s"
    lines = out.stdout.strip().splitlines()
    failed = [line for line in lines if line.startswith(("FAILED ", "ERROR "))] or lines[-3:]
    return out.returncode == 0, time.perf_counter() - start, "\n".join(failed)[:300]


def check_imports(tree: Path) -> None:
    """The copy's packages, not the working tree's, must be the ones imported there."""
    code = "import deploy, drivers, sim_fallback; print(drivers.__file__, deploy.__file__, sim_fallback.__file__)"
    out = subprocess.run([sys.executable, "-c", code], cwd=tree, env={**os.environ, "PYTHONPATH": str(tree)},
                         capture_output=True, text=True, check=True).stdout
    if any(not Path(p).is_relative_to(tree) for p in out.split()):
        sys.exit(f"mutate: the copy at {tree} imports packages from elsewhere ({out.strip()}): check PYTHONPATH")


def original_text(tree: Path, mutant: Mutant) -> str:
    """The text of the mutant's file; LookupError unless the mutant's text occurs in it exactly once."""
    text = (tree / mutant.path).read_text()
    if text.count(mutant.old) != 1:
        raise LookupError(f"mutant {mutant.name}: its text occurs {text.count(mutant.old)} times in {mutant.path} "
                          "(expected once): the code changed; update the mutant in scripts/mutate.py")
    return text


def run(mutants: list[Mutant], report) -> list[dict]:
    """Baseline, then every mutant in one temporary copy (restored after each); one result dict per mutant."""
    with tempfile.TemporaryDirectory(prefix="axisloop-mutate-") as tmp:
        tree = Path(tmp) / "axisloop"
        copy_checkout(tree)
        check_imports(tree)
        for mutant in mutants:  # every mutant must still match before anything slow runs
            original_text(tree, mutant)
        targets = tuple(dict.fromkeys(t for m in mutants for t in m.tests))
        passed, seconds, failed = run_tests(tree, targets)
        if not passed:
            raise RuntimeError(f"the unmutated tests fail ({seconds:.0f} s), so no mutant can be judged:\n{failed}")
        report(f"baseline: {len(targets)} test targets pass ({seconds:.0f} s)")
        results = []
        for mutant in mutants:
            file = tree / mutant.path
            original = original_text(tree, mutant)
            file.write_text(original.replace(mutant.old, mutant.new))
            try:
                passed, seconds, failed = run_tests(tree, mutant.tests)
            finally:
                file.write_text(original)
            result = {"name": mutant.name, "bug": mutant.bug, "file": mutant.path,
                      "status": "survived" if passed else "killed", "seconds": round(seconds, 1)}
            if not passed:
                result["killed_by"] = failed.splitlines()[0]
            results.append(result)
            report(f"{result['status']:8} {mutant.name:45} {seconds:5.0f} s  {mutant.bug}")
    return results


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("prefixes", nargs="*", help="only the mutants whose names start with one of these")
    parser.add_argument("--list", action="store_true", help="list the mutants, run nothing")
    parser.add_argument("--json", action="store_true", help="print the results as JSON")
    args = parser.parse_args(argv)
    mutants = [m for m in MUTANTS if not args.prefixes or m.name.startswith(tuple(args.prefixes))]
    if not mutants:
        print(f"mutate: no mutant starts with {' or '.join(args.prefixes)} (see --list)", file=sys.stderr)
        return 2
    if args.list:
        for m in mutants:
            print(f"{m.name:45} {m.path:32} {m.bug}")
        return 0
    report = (lambda line: print(line, file=sys.stderr, flush=True)) if args.json else print
    try:
        results = run(mutants, report)
    except (LookupError, RuntimeError) as exc:
        print(f"mutate: {exc}", file=sys.stderr)
        return 2
    killed = sum(r["status"] == "killed" for r in results)
    summary = {"killed": killed, "survived": len(results) - killed, "total": len(results),
               "score": round(killed / len(results), 3), "mutants": results}
    if args.json:
        print(json.dumps(summary, indent=1))
    else:
        print(f"mutation score: {killed}/{len(results)} killed ({100 * killed / len(results):.0f} %)")
        for r in results:
            if r["status"] == "survived":
                print(f"  survived: {r['name']} ({r['bug']}, {r['file']})")
    return 0 if killed == len(results) else 1


if __name__ == "__main__":
    sys.exit(main())

"""Nothing the user has is lost or replaced unasked: a refused command keeps the old output and makes no new
one; `--overwrite` never removes the recording a command reads, nor a folder holding anything deploy does not
write there; a failed export or track leaves nothing half-written; `--rrd` and `sim show --out` never replace a
file unasked; a tracked copy keeps the `first` and `grasped` marks."""

import json
import shutil
from pathlib import Path

import pytest
from cli_run import one_line, run, small_recording

from drivers.camera.frames_dir import FramesRecording

BOX = ("--segmenter", "classical", "--box", "40", "30", "120", "90")


def _files(path: Path) -> dict[str, bytes]:
    return {str(p.relative_to(path)): p.read_bytes() for p in sorted(path.rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """A small simulated recording without masks (6 frames, 160x120)."""
    return small_recording(tmp_path_factory.mktemp("rec") / "rec")


@pytest.fixture
def run_dir(tmp_path):
    """An earlier run folder."""
    path = tmp_path / "run"
    path.mkdir()
    (path / "steps.json").write_text("{}")
    (path / "episode.rrd").write_text("old")
    return path


def test_a_refused_open_keeps_the_old_run_folder_and_makes_no_new_one(capsys, tmp_path, monkeypatch, run_dir):
    monkeypatch.chdir(tmp_path)
    before = _files(run_dir)
    for bad, words in ((("--distance", "5"), "invalid value for --distance"),
                       (("--segmenter", "nosuch"), "unknown segmenter 'nosuch'")):
        code, _, err = run(capsys, "open-drawer", *bad, "--run-dir", run_dir, "--overwrite")
        assert code == 2 and words in one_line(err)
        assert _files(run_dir) == before
    code, _, err = run(capsys, "open-drawer", "--distance", "5")
    assert code == 2 and not (tmp_path / "runs").exists()


def test_a_command_whose_camera_fails_to_open_keeps_the_old_output(capsys, tmp_path, monkeypatch, run_dir,
                                                                   recording):
    monkeypatch.chdir(tmp_path)
    before = _files(run_dir)
    missing = ("--camera", f"replay:{tmp_path / 'missing'}")
    code, _, err = run(capsys, "open-drawer", *missing, "--arm", "ideal", "--robot", "panda_sim", "--dry-run",
                       "--run-dir", run_dir, "--overwrite")
    assert code == 2 and "not found" in one_line(err) and _files(run_dir) == before
    code, _, err = run(capsys, "open-drawer", *missing, "--arm", "ideal", "--robot", "panda_sim", "--dry-run")
    assert code == 2 and list((tmp_path / "runs").iterdir()) == []  # no empty runs/drawer-TIME left
    old = tmp_path / "old"
    shutil.copytree(recording, old)
    before = _files(old)
    code, _, err = run(capsys, "record", *missing, "--frames", "2", "--out", old, "--overwrite")
    assert code == 2 and "not found" in one_line(err) and _files(old) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old", "run", "runs"]  # nothing set aside is left


def test_overwrite_never_removes_the_recording_the_command_reads(capsys, tmp_path, recording):
    run_dir = tmp_path / "run"
    shutil.copytree(recording, run_dir / "frames")
    (run_dir / "steps.json").write_text("{}")
    before = _files(run_dir)
    code, _, err = run(capsys, "open-drawer", "--camera", f"replay:{run_dir / 'frames'}", "--arm", "ideal",
                       "--robot", "panda_sim", "--dry-run", "--run-dir", run_dir, "--overwrite")
    assert code == 2 and f"--run-dir {run_dir} holds the recording" in one_line(err)
    assert _files(run_dir) == before
    rec = tmp_path / "rec"
    shutil.copytree(recording, rec)
    before = _files(rec)
    code, _, err = run(capsys, "record", "--camera", f"replay:{rec}", "--out", rec, "--overwrite", "--frames", "2")
    assert code == 2 and f"--out {rec} is the recording" in one_line(err) and _files(rec) == before


@pytest.mark.parametrize("stranger", ["notes.txt", "frames/notes.txt", "color/notes.txt"])
def test_overwrite_removes_only_a_folder_that_holds_nothing_else(capsys, tmp_path, recording, stranger):
    out = tmp_path / "userdata"
    shutil.copytree(recording, out / "frames" if stranger.startswith("frames") else out)
    if stranger.startswith("frames"):
        (out / "steps.json").write_text("{}")  # a run folder
    (out / stranger).write_text("keep me")
    before = _files(out)
    writers = [("open-drawer", "--dry-run", "--run-dir", out, "--overwrite")] if stranger.startswith("frames") else \
        [("record", "--camera", "sim", "--frames", "1", "--out", out, "--overwrite"),
         ("sim", "record", "--out", out, "--overwrite")]
    for writer in writers:
        code, _, err = run(capsys, *writer)
        assert code == 2 and f"holds {stranger}, which deploy never writes there" in one_line(err)
        assert _files(out) == before


def test_overwrite_clears_the_leftovers_of_a_killed_command_and_nothing_else(capsys, tmp_path, recording):
    """After a kill -9: a track's hidden masks inside the recording and an earlier overwrite's old recording set
    aside beside it. Their exact names are deploy's; near misses, and a set-aside folder with more, stay."""
    out = tmp_path / "rec"
    shutil.copytree(recording, out)
    (out / ".mask-0123abcd.partial").mkdir()
    (out / ".mask-0123abcd.partial" / "000000.png").write_bytes(b"half")
    shutil.copytree(recording, tmp_path / ".rec.replaced-0a1b2c3d")  # the old one set aside, never removed
    for mine in (".rec.replaced-backup", ".other.replaced-0a1b2c3d", "rec.replaced-0a1b2c3d", ".rec.replaced-fedcba98"):
        shutil.copytree(recording, tmp_path / mine)
    (tmp_path / ".rec.replaced-fedcba98" / "notes.txt").write_text("keep me")
    code, _, err = run(capsys, "record", "--camera", "sim", "--frames", "1", "--out", out, "--overwrite")
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == [".other.replaced-0a1b2c3d", ".rec.replaced-backup",
                                                          ".rec.replaced-fedcba98", "rec", "rec.replaced-0a1b2c3d"]
    assert len(FramesRecording(out)) == 1 and not list(out.glob(".*"))
    for stranger in (".mask-0123abcd.partial/notes.txt", ".mask-notes.partial", ".mask-0123abcd.partial.txt",
                     ".notes.replaced-0a1b2c3d.bak"):
        (out / stranger).parent.mkdir(exist_ok=True)
        (out / stranger).write_text("keep me")
        before = _files(out)
        code, _, err = run(capsys, "record", "--camera", "sim", "--frames", "1", "--out", out, "--overwrite")
        assert code == 2 and f"holds {stranger}, which deploy never writes there" in one_line(err), stranger
        assert _files(out) == before
        shutil.rmtree(out / stranger.split("/")[0]) if "/" in stranger else (out / stranger).unlink()

def test_export_overwrite_keeps_a_dataset_with_files_of_its_own(capsys, tmp_path, recording):
    out = tmp_path / "tum"
    assert run(capsys, "export", recording, "--format", "tum", "--out", out)[0] == 0
    (out / "accelerometer.txt").write_text("0.0 0 0 9.81")
    before = _files(out)
    code, _, err = run(capsys, "export", recording, "--format", "tum", "--out", out, "--overwrite")
    assert code == 2 and "not a tum export (it holds accelerometer.txt" in one_line(err) and _files(out) == before


def test_a_failed_export_leaves_nothing_and_keeps_the_earlier_export(capsys, tmp_path, recording):
    bad = tmp_path / "bad"
    shutil.copytree(recording, bad)
    (bad / "depth" / "000003.png").unlink()  # a frame in the middle: read after three were written
    for fmt, name in (("tum", "tum"), ("open3d", "o3d"), ("rrd", "x.rrd")):
        code, _, err = run(capsys, "export", bad, "--format", fmt, "--out", tmp_path / name)
        assert code == 2 and "000003.png is missing" in one_line(err)
        assert [p.name for p in tmp_path.iterdir()] == ["bad"]  # no export, no partial folder beside it
    earlier = tmp_path / "earlier"
    assert run(capsys, "export", recording, "--format", "tum", "--out", earlier)[0] == 0
    before = _files(earlier)
    code, _, err = run(capsys, "export", bad, "--format", "tum", "--out", earlier, "--overwrite")
    assert code == 2 and _files(earlier) == before and sorted(p.name for p in tmp_path.iterdir()) == ["bad",
                                                                                                      "earlier"]


def test_rrd_never_replaces_a_file_unasked_nor_writes_into_the_recording(capsys, tmp_path, recording):
    rec = tmp_path / "rec"
    shutil.copytree(recording, rec)
    before = _files(rec)
    code, _, err = run(capsys, "track", rec, *BOX, "--out", tmp_path / "copy", "--rrd", rec / "frames.jsonl")
    assert code == 2 and f"--rrd {rec / 'frames.jsonl'} lies inside the recording" in one_line(err)
    assert _files(rec) == before and not (tmp_path / "copy").exists()
    assert run(capsys, "track", rec, *BOX, "--out", tmp_path / "copy")[0] == 0  # a copy with masks to estimate on
    copy = _files(tmp_path / "copy")
    code, _, err = run(capsys, "axis", "estimate", tmp_path / "copy", "--rrd", tmp_path / "copy" / "frames.jsonl")
    assert code == 2 and "lies inside the recording" in one_line(err) and _files(tmp_path / "copy") == copy
    mine = tmp_path / "mine.rrd"
    mine.write_text("keep me")
    code, _, err = run(capsys, "axis", "estimate", tmp_path / "copy", "--rrd", mine)
    assert code == 2 and "already exists: refusing to replace it; choose another --rrd" in one_line(err)
    code, _, err = run(capsys, "track", rec, *BOX, "--out", tmp_path / "copy2", "--rrd", mine)
    assert code == 2 and "pass --overwrite to replace it" in one_line(err) and mine.read_text() == "keep me"
    assert run(capsys, "track", rec, *BOX, "--out", tmp_path / "copy2", "--rrd", mine, "--overwrite")[0] == 0
    assert mine.read_bytes() != b"keep me"


def test_a_failed_track_leaves_no_mask_folder(capsys, tmp_path, recording):
    rec = tmp_path / "rec"
    shutil.copytree(recording, rec)
    (rec / "depth" / "000003.png").rename(tmp_path / "000003.png")  # tracking fails on the fourth frame
    names = sorted(p.name for p in rec.iterdir())
    code, _, err = run(capsys, "track", rec, *BOX)
    assert code == 2 and "000003.png is missing" in one_line(err)
    assert sorted(p.name for p in rec.iterdir()) == names  # no mask/, no partial one beside it
    (tmp_path / "000003.png").rename(rec / "depth" / "000003.png")
    code, _, err = run(capsys, "track", rec, *BOX)
    assert code == 0, err
    assert len(list((rec / "mask").iterdir())) == 6 and FramesRecording(rec).has_masks


def test_a_tracked_copy_keeps_the_first_and_grasped_marks(capsys, tmp_path, recording):
    rec = tmp_path / "rec"
    shutil.copytree(recording, rec)
    lines = [json.loads(line) for line in (rec / "frames.jsonl").read_text().splitlines()]
    for i in (0, 3):  # a run that looked again from the start on frame 3
        lines[i]["first"] = True
    for i, held in enumerate((False, None, True, True, False, True)):  # the gripper held; unmarked on frame 1
        if held is not None:
            lines[i]["grasped"] = held
    (rec / "frames.jsonl").write_text("".join(json.dumps(line) + "\n" for line in lines))
    assert run(capsys, "track", rec, *BOX, "--out", tmp_path / "copy")[0] == 0
    copied = FramesRecording(tmp_path / "copy").records
    assert [r.get("first") for r in copied] == [True, None, None, True, None, None]
    assert [r.get("grasped", "absent") for r in copied] == [False, "absent", True, True, False, True]


def test_sim_show_checks_its_out_before_rendering_and_replaces_only_with_overwrite(capsys, tmp_path):
    code, _, err = run(capsys, "sim", "show", "--out", tmp_path / "drawer1")
    assert code == 2 and "give a file name ending in .png" in one_line(err)
    assert list(tmp_path.iterdir()) == []
    png = tmp_path / "scene.png"
    png.write_text("keep me")
    code, _, err = run(capsys, "sim", "show", "--out", png)
    assert code == 2 and "already exists: pass --overwrite" in one_line(err) and png.read_text() == "keep me"
    assert run(capsys, "sim", "show", "--out", png, "--overwrite")[0] == 0
    assert png.read_bytes().startswith(b"\x89PNG")


def test_overwrite_never_replaces_another_kind_of_output(capsys, tmp_path, recording, run_dir):
    """`sim record --out RUN --overwrite` had removed a run folder's steps.json and report.png, saying "a recording
    is already there"; `open --run-dir REC --overwrite` a recording's masks and truth."""
    before = _files(run_dir)
    code, _, err = run(capsys, "sim", "record", "--out", run_dir, "--overwrite", "--fps", "1")
    assert code == 2 and f"--out {run_dir} holds a run folder, not a recording" in one_line(err)
    assert _files(run_dir) == before
    rec = tmp_path / "rec"
    shutil.copytree(recording, rec)
    before = _files(rec)
    code, _, err = run(capsys, "open-door", "--dry-run", "--run-dir", rec, "--overwrite")
    assert code == 2 and f"--run-dir {rec} holds a recording, not a run folder" in one_line(err)
    assert _files(rec) == before


def test_a_set_aside_output_of_another_kind_or_with_nothing_replaced_stays(tmp_path, recording):
    """A killed overwrite's old run folder beside NAME is not removed by a recording written to NAME: not of that
    kind, and with nothing at NAME being replaced it may be the only copy."""
    from deploy.output_folder import new_output

    aside = tmp_path / ".x.replaced-0123abcd"
    aside.mkdir()
    (aside / "steps.json").write_text("{}")
    (aside / "report.png").write_bytes(b"png")
    with new_output(tmp_path / "x", True, "recording") as out:
        out.mkdir(exist_ok=True)
        (out / "meta.json").write_text("{}")
    assert (aside / "steps.json").is_file()
    shutil.rmtree(tmp_path / "x")
    shutil.copytree(recording, tmp_path / "x")
    with new_output(tmp_path / "x", True, "recording") as out:  # replacing a recording: a run folder still stays
        out.mkdir(exist_ok=True)
        (out / "meta.json").write_text("{}")
    assert (aside / "steps.json").is_file()

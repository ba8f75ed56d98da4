"""The frames-directory recording format (version 1): writer, reader and replay camera.

Layout (see docs/recording-format.md): `meta.json`, `frames.jsonl` (one JSON object per frame),
`color/NNNNNN.png` (8-bit RGB), `depth/NNNNNN.png` (16-bit depth units), optional `mask/NNNNNN.png`.
"""

from __future__ import annotations

import functools
import json
import math
import os
import shutil
import time
from pathlib import Path

import cv2
import numpy as np

from drivers.camera.base import Camera, Frame, Intrinsics
from drivers.errors import CameraError, RecordingError

FORMAT = "axisloop-frames"
RUN_FRAMES = "frames"  # a run folder's recording
VERSION = 1
DEPTH_SCALE = 0.001  # metres per depth unit unless the writer is told otherwise (millimetres)
_INTRINSICS_FIELDS = ("width", "height", "fx", "fy", "cx", "cy")


def _png_name(index: int) -> str:
    return f"{index:06d}.png"


def _pose_list(pose: np.ndarray | None, what: str) -> list[list[float]] | None:
    if pose is None:
        return None
    pose = np.asarray(pose, np.float64)
    if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
        raise ValueError(f"{what} must be a finite 4x4 matrix, got shape {pose.shape}")
    return pose.tolist()


class FramesWriter:
    """Writes a frames recording; every frame is on disk before `write` returns (its PNGs and their directory
    entries fsynced, then its frames.jsonl line flushed and fsynced), so a reader in another process sees it at
    once and a crash or power cut afterwards cannot lose it.

    `with FramesWriter(path, intrinsics) as w: w.write(frame, mask=...)`. An existing frames recording at `path`
    is refused unless the caller says it replaces it (`replace=True`: the whole folder is removed first, so no file
    of the old recording survives); any other non-empty directory is always refused. `camera` (the spec it came
    from) and `simulated` (frames rendered by a simulator) go to meta.json: they choose the filter profile on replay;
    so does `min_range_m`, the camera's minimum range (None: not known), which perception drops depth below.
    `robot`: the robot config the joints belong to (a shipped config's name or a file), where given.
    """

    def __init__(
        self,
        path: str | Path,
        intrinsics: Intrinsics,
        depth_scale: float = DEPTH_SCALE,
        T_base_camera: np.ndarray | None = None,
        camera: str | None = None,
        simulated: bool = False,
        replace: bool = False,
        min_range_m: float | None = None,
        robot: str | None = None,
    ) -> None:
        if not (math.isfinite(depth_scale) and depth_scale > 0):
            raise ValueError(f"depth_scale must be a positive number of metres per unit, got {depth_scale}")
        self.path = Path(path)
        self.intrinsics = intrinsics
        self.depth_scale = float(depth_scale)
        self._pose = None if T_base_camera is None else np.asarray(T_base_camera, np.float64)
        meta = {
            "format": FORMAT,
            "version": VERSION,
            "intrinsics": intrinsics.to_dict(),
            "depth_scale": self.depth_scale,
            "T_base_camera": _pose_list(T_base_camera, "T_base_camera"),
            "camera": camera,
            "simulated": bool(simulated),
            "min_range_m": min_range_m,
        }
        if robot is not None:
            meta["robot"] = robot
        self._prepare_directory(replace)
        for sub in ("color", "depth"):
            (self.path / sub).mkdir()
        _write_durably(self.path / "meta.json", (json.dumps(meta, indent=2) + "\n").encode())
        self._jsonl = open(self.path / "frames.jsonl", "a", encoding="utf-8")
        self._sync_directory(self.path)
        self._sync_directory(self.path.parent)
        self._count = 0
        self.depth_out_of_range_px = 0  # depth pixels stored as no depth: beyond the 16-bit range (`depth_units`)

    def _prepare_directory(self, replace: bool) -> None:
        if self.path.exists() and not self.path.is_dir():
            raise RecordingError(f"cannot record to {self.path}: it is a file; choose a directory path")
        if self.path.is_dir() and any(self.path.iterdir()):
            if not _is_frames_recording(self.path):
                raise RecordingError(
                    f"refusing to record into {self.path}: the directory is not empty and is not a frames "
                    "recording; choose a new or empty directory"
                )
            if not replace:
                raise RecordingError(
                    f"refusing to record into {self.path}: a recording is already there; choose another directory, "
                    "or replace it on purpose (deploy commands: --overwrite)"
                )
            shutil.rmtree(self.path)  # the whole recording: a shorter new one must not keep old frames or truth.json
        self.path.mkdir(parents=True, exist_ok=True)

    def write(
        self,
        frame: Frame,
        mask: np.ndarray | None = None,
        joint_positions: np.ndarray | list[float] | None = None,
        ee_pose: np.ndarray | None = None,
        first: bool = False,
        grasped: bool | None = None,
        joint_commands: np.ndarray | list[float] | None = None,
        gripper_width_m: float | None = None,
    ) -> None:
        """Append one frame (`mask` defaults to `frame.mask`); its PNGs first, then its frames.jsonl line.
        `joint_commands`: the joint positions commanded at this frame; `gripper_width_m`: the gripper's opening.
        `first`: the object's body box was fixed on this frame (a run that looked again from the start).
        `grasped`: whether the gripper held the handle at this frame, written only when given (a writer that
        knows it: `deploy sim record`, run folders); `deploy axis estimate` then fits `ee_pose` only where true."""
        if self._jsonl.closed:
            raise RecordingError(f"cannot write to {self.path}: the writer is closed")
        h, w = self.intrinsics.height, self.intrinsics.width
        color = np.asarray(frame.color)
        if color.shape != (h, w, 3) or color.dtype != np.uint8:
            raise RecordingError(
                f"frame {frame.index}: colour must be ({h}, {w}, 3) uint8 to match the recording's "
                f"intrinsics, got {color.shape} {color.dtype}"
            )
        depth = np.asarray(frame.depth_m, np.float64)
        if depth.shape != (h, w):
            raise RecordingError(f"frame {frame.index}: depth must be ({h}, {w}), got {depth.shape}")
        mask = frame.mask if mask is None else mask
        if mask is not None and np.shape(mask) != (h, w):
            raise RecordingError(f"frame {frame.index}: mask must be ({h}, {w}), got {np.shape(mask)}")

        name = _png_name(self._count)
        _write_png(self.path / "color" / name, cv2.cvtColor(color, cv2.COLOR_RGB2BGR))
        units, beyond = depth_units(depth, self.depth_scale)
        self.depth_out_of_range_px += beyond
        _write_png(self.path / "depth" / name, units)
        written = ["color", "depth"]
        if mask is not None:
            if not (self.path / "mask").is_dir():
                (self.path / "mask").mkdir()
                self._sync_directory(self.path)
            _write_png(self.path / "mask" / name, np.where(np.asarray(mask, bool), 255, 0).astype(np.uint8))
            written.append("mask")
        for sub in written:  # the PNGs' names must be on disk before the line that lists them
            self._sync_directory(self.path / sub)

        record: dict = {"index": self._count, "t": float(frame.t)}
        if joint_positions is not None:
            record["joint_positions"] = [float(v) for v in np.ravel(joint_positions)]
        if joint_commands is not None:
            record["joint_commands"] = [float(v) for v in np.ravel(joint_commands)]
        if gripper_width_m is not None:
            record["gripper_width_m"] = float(gripper_width_m)
        if ee_pose is not None:
            record["ee_pose"] = _pose_list(ee_pose, "ee_pose")
        if first:
            record["first"] = True
        if grasped is not None:
            record["grasped"] = bool(grasped)
        pose = frame.T_base_camera  # a camera that moves (eye-in-hand): its pose per frame, where not meta.json's
        if pose is not None and not (self._pose is not None and np.allclose(pose, self._pose, rtol=0, atol=1e-9)):
            record["T_base_camera"] = _pose_list(pose, "T_base_camera")
        self._jsonl.write(json.dumps(record) + "\n")
        self._jsonl.flush()
        os.fsync(self._jsonl.fileno())
        self._count += 1

    def close(self) -> None:
        """Close frames.jsonl (idempotent)."""
        self._jsonl.close()

    @staticmethod
    def _sync_directory(path: Path) -> None:
        """fsync a directory: the names of the files created in it reach the disk."""
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)

    def __enter__(self) -> FramesWriter:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def depth_units(depth_m: np.ndarray, depth_scale: float) -> tuple[np.ndarray, int]:
    """Depth in metres as the 16-bit units of `depth_scale` m a depth PNG stores, and how many pixels were
    beyond its range (65535 units): those become 0, no depth, never a wrong depth."""
    depth = np.asarray(depth_m, np.float64)
    units = np.where(np.isfinite(depth) & (depth > 0), np.round(depth / depth_scale), 0.0)
    beyond = units > 65535
    return np.where(beyond, 0.0, units).astype(np.uint16), int(np.count_nonzero(beyond))


def _write_durably(path: Path, data: bytes) -> None:
    with open(path, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())


def _write_png(path: Path, image: np.ndarray) -> None:
    ok, encoded = cv2.imencode(".png", image)
    if not ok:
        raise RecordingError(f"could not encode {path} as PNG")
    _write_durably(path, encoded.tobytes())


def _is_frames_recording(path: Path) -> bool:
    try:
        meta = json.loads((path / "meta.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return False
    return isinstance(meta, dict) and meta.get("format") == FORMAT


def recording_path(path: str | Path) -> Path:
    """`path`, or the recording a run folder holds (RUN/frames, docs/recording-format.md) when `path` is one."""
    path = Path(path)
    if not (path / "meta.json").exists() and _is_frames_recording(path / RUN_FRAMES):
        return path / RUN_FRAMES
    return path


class _FieldError(ValueError):
    """A frames.jsonl field of the wrong kind, with the fix to name (the generic one speaks of index and t)."""

    def __init__(self, cause: str, fix: str) -> None:
        super().__init__(cause)
        self.fix = fix


def _finite(value: object) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _check_record(record: object) -> None:
    """ValueError unless `record` is a frames.jsonl object: index an integer >= 0, t finite, joint_positions
    finite numbers, ee_pose and T_base_camera finite 4x4 matrices and grasped true or false where given."""
    if not isinstance(record, dict):
        raise ValueError("not a JSON object")
    index, t = record["index"], float(record["t"])
    if not isinstance(index, int) or isinstance(index, bool) or index < 0:
        raise ValueError(f"index {index!r} is not an integer >= 0")
    if not math.isfinite(t):
        raise ValueError(f"t {t} is not finite")
    for name in ("joint_positions", "joint_commands"):
        q = record.get(name)
        if q is not None and not (isinstance(q, list) and all(_finite(v) for v in q)):
            raise ValueError(f"{name} is not a list of finite numbers")
    if "gripper_width_m" in record and not _finite(record["gripper_width_m"]):
        raise ValueError("gripper_width_m is not a finite number")
    for name in ("ee_pose", "T_base_camera"):
        pose = record.get(name)
        if pose is not None and (np.shape(pose) != (4, 4) or not np.all(np.isfinite(np.asarray(pose, np.float64)))):
            raise ValueError(f"{name} is not a finite 4x4 matrix")
    if "grasped" in record and not isinstance(record["grasped"], bool):
        raise _FieldError(f"grasped is {json.dumps(record['grasped'])[:40]}, not true or false",
                          "write grasped as the JSON boolean true or false, or remove the key")


class FramesRecording:
    """Reads a frames recording; meta.json is validated on open, frames.jsonl read on first use.

    An interrupted recording (a last frames.jsonl line without its newline or not valid JSON, or missing PNGs
    of the last listed frame) is read up to its last complete frame. Frame times `t` must increase.
    """

    def __init__(self, path: str | Path) -> None:
        self.path = recording_path(path)
        if not self.path.is_dir():
            raise RecordingError(
                f"recording {self.path} not found: no such directory; pass the directory holding meta.json"
            )
        meta = self._read_meta()
        self.intrinsics: Intrinsics = meta["intrinsics"]
        self.depth_scale: float = meta["depth_scale"]
        self.T_base_camera: np.ndarray | None = meta["T_base_camera"]
        self.camera: str | None = meta["camera"]
        self.min_range_m: float | None = meta["min_range_m"]
        """The recording camera's minimum range (m), when meta.json says it."""
        self.robot: str | None = meta["robot"]
        """The robot config the joints belong to (a shipped config's name or a file), where the writer knew it."""
        self.simulated: bool = meta["simulated"] or (self.path / "truth.json").is_file()
        """Rendered by a simulator: meta.json says so, or the recording holds the simulator's truth.json."""
        self._records: list[dict] | None = None

    def _read_meta(self) -> dict:
        file = self.path / "meta.json"
        fix = "re-record, or write a meta.json as described in docs/recording-format.md"
        try:
            meta = json.loads(file.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise RecordingError(f"{file} is missing: {self.path} is not a frames recording; {fix}") from None
        except (OSError, ValueError, RecursionError) as e:
            raise RecordingError(f"{file} is not valid JSON ({e}); {fix}") from None
        if not isinstance(meta, dict) or meta.get("format") != FORMAT:
            got = meta.get("format") if isinstance(meta, dict) else type(meta).__name__
            raise RecordingError(f"{file}: format is {got!r}, expected {FORMAT!r}; {fix}")
        if meta.get("version") != VERSION:
            raise RecordingError(
                f"{file}: unsupported format version {meta.get('version')!r} (this axisloop reads version "
                f"{VERSION}); convert the recording or use a matching axisloop release"
            )
        raw = meta.get("intrinsics")
        if not isinstance(raw, dict):
            raise RecordingError(f"{file}: 'intrinsics' is missing or not an object; {fix}")
        missing = [k for k in _INTRINSICS_FIELDS if k not in raw]
        if missing:
            raise RecordingError(f"{file}: intrinsics field(s) {', '.join(missing)} missing; {fix}")
        try:
            intr = Intrinsics(
                int(raw["width"]), int(raw["height"]), *(float(raw[k]) for k in ("fx", "fy", "cx", "cy")),
                raw.get("distortion", "none"), tuple(float(c) for c in raw.get("coeffs", [0.0] * 5)),
            )
            depth_scale = float(meta.get("depth_scale", DEPTH_SCALE))
            min_range = meta.get("min_range_m")
            min_range = None if min_range is None else float(min_range)
            pose = meta.get("T_base_camera")
            pose = None if pose is None else np.asarray(pose, np.float64)
        except (TypeError, ValueError, OverflowError) as e:
            raise RecordingError(f"{file}: a field has the wrong type ({e}); {fix}") from None
        if min(intr.width, intr.height) <= 0 or not all(
            math.isfinite(v) and v > 0 for v in (intr.fx, intr.fy)
        ) or not all(math.isfinite(v) for v in (intr.cx, intr.cy)):
            raise RecordingError(f"{file}: intrinsics {intr.to_dict()} are not a valid camera; {fix}")
        if not (math.isfinite(depth_scale) and depth_scale > 0):
            raise RecordingError(f"{file}: depth_scale must be positive (m/unit), not {depth_scale}; {fix}")
        if min_range is not None and not (math.isfinite(min_range) and min_range >= 0):
            raise RecordingError(f"{file}: min_range_m must be a distance >= 0 (m) or null, not {min_range}; {fix}")
        if not all(math.isfinite(c) for c in intr.coeffs):
            raise RecordingError(f"{file}: intrinsics coeffs must be finite numbers, not {list(intr.coeffs)}; {fix}")
        if pose is not None and (pose.shape != (4, 4) or not np.all(np.isfinite(pose))):
            raise RecordingError(f"{file}: T_base_camera must be a 4x4 row-major nested list or null; {fix}")
        camera, simulated, robot = meta.get("camera"), meta.get("simulated", False), meta.get("robot")
        if not all(v is None or isinstance(v, str) for v in (camera, robot)) or not isinstance(simulated, bool):
            raise RecordingError(f"{file}: camera and robot must be strings or null and simulated true or false; "
                                 f"{fix}")
        return {"intrinsics": intr, "depth_scale": depth_scale, "T_base_camera": pose, "camera": camera,
                "simulated": simulated, "min_range_m": min_range, "robot": robot}

    @property
    def records(self) -> list[dict]:
        """The frames.jsonl objects of the complete frames, in order."""
        if self._records is None:
            self._records = self._read_records()
        return self._records

    def _read_records(self) -> list[dict]:
        file = self.path / "frames.jsonl"
        if not file.exists():
            return []
        try:
            lines = file.read_text(encoding="utf-8").split("\n")
        except UnicodeDecodeError as e:
            raise RecordingError(f"{file} is not UTF-8 text ({e.reason} at byte {e.start}): it is damaged; "
                                 "restore it from a copy or re-record") from None
        last = max((n for n, line in enumerate(lines, start=1) if line.strip()), default=0)
        records, previous = [], None
        for number, line in enumerate(lines, start=1):
            if not line.strip():
                continue
            parsed = False
            try:
                record = json.loads(line)
                parsed = True
                _check_record(record)
            except (ValueError, KeyError, TypeError, RecursionError) as e:
                if number == len(lines) or (number == last and not parsed):  # interrupted mid-line
                    break
                fix = getattr(e, "fix", "each line must be a JSON object with 'index' and 't'; remove or fix the line")
                raise RecordingError(f"{file}, line {number}: not a frame record ({e}); {fix}") from None
            if previous is not None and float(record["t"]) <= previous[1]:
                raise RecordingError(
                    f"{file}, line {number}: t {record['t']} does not come after line {previous[0]}'s t "
                    f"{previous[1]}: frame times must increase; fix or remove the line"
                )
            previous = number, float(record["t"])
            records.append(record)
        if records and not all(self._png(records[-1], s).exists() for s in ("color", "depth")):
            records.pop()  # interrupted while writing the last frame's images
        return records

    def _png(self, record: dict, sub: str) -> Path:
        return self.path / sub / _png_name(int(record["index"]))

    def __len__(self) -> int:
        return len(self.records)

    @functools.cached_property
    def marks_grasp(self) -> bool:
        """Whether the recording says when the gripper held the handle (`grasped` on any frame)."""
        return any("grasped" in r for r in self.records)

    def held_pose(self, i: int) -> np.ndarray | None:
        """Frame `i`'s gripper pose (`ee_pose`, 0-based position) where it is the held handle's: every recorded
        pose when the recording does not say when the gripper held (`marks_grasp`), else only those of the frames
        marked `grasped` true (the approach, and a grip that slipped, move the gripper and not the part)."""
        record = self.records[i]
        pose = record.get("ee_pose")
        if pose is None or (self.marks_grasp and record.get("grasped") is not True):
            return None
        return np.asarray(pose, np.float64)

    @property
    def has_masks(self) -> bool:
        """Whether any frame has a mask (`unmasked` lists the frames without one)."""
        return any(self._png(r, "mask").exists() for r in self.records)  # stops at the first

    @property
    def unmasked(self) -> list[int]:
        """The indices of the frames without a mask PNG."""
        return [int(r["index"]) for r in self.records if not self._png(r, "mask").exists()]

    def frame(self, i: int) -> Frame:
        """Frame `i` (0-based position in frames.jsonl): RGB colour, depth in metres, mask if recorded."""
        n = len(self)
        if not -n <= i < n:
            raise IndexError(f"frame {i} out of range: {self.path} has {n} frames")
        record = self.records[i]
        h, w = self.intrinsics.height, self.intrinsics.width
        color = self._load(record, "color", np.uint8, 3)
        depth = self._load(record, "depth", np.uint16, None)
        mask = None
        if self._png(record, "mask").exists():
            mask = self._load(record, "mask", np.uint8, None) > 0
        for name, image in (("colour", color), ("depth", depth), ("mask", mask)):
            if image is not None and image.shape[:2] != (h, w):
                raise RecordingError(
                    f"{self.path}: {name} image of frame {record['index']} is "
                    f"{image.shape[1]}x{image.shape[0]} but meta.json intrinsics say {w}x{h}; "
                    "fix meta.json or re-record"
                )
        return Frame(
            index=int(record["index"]),
            t=float(record["t"]),
            color=cv2.cvtColor(color, cv2.COLOR_BGR2RGB),
            depth_m=(depth * self.depth_scale).astype(np.float32),
            intrinsics=self.intrinsics,
            T_base_camera=np.asarray(record["T_base_camera"], np.float64) if "T_base_camera" in record
            else None if self.T_base_camera is None else self.T_base_camera.copy(),
            mask=mask,
        )

    def _load(self, record: dict, sub: str, dtype: type, channels: int | None) -> np.ndarray:
        file = self._png(record, sub)
        if not file.exists():
            raise RecordingError(
                f"{file} is missing (listed in frames.jsonl); restore it or remove the frame's line"
            )
        image = cv2.imread(str(file), cv2.IMREAD_UNCHANGED)
        if image is None:
            raise RecordingError(f"{file} is not a readable PNG; restore it or remove the frame's line")
        want = f"{np.dtype(dtype).name} with {channels or 1} channel(s)"
        got_channels = 1 if image.ndim == 2 else image.shape[2]
        if image.dtype != dtype or got_channels != (channels or 1):
            raise RecordingError(
                f"{file} is {image.dtype.name} with {got_channels} channel(s), expected {want} "
                "(colour 8-bit RGB, depth 16-bit units, mask 8-bit); re-export it"
            )
        return image


class FramesReplayCamera(Camera):
    """Plays a frames recording as a camera (`--camera replay:PATH`).

    realtime: sleep to honour the recorded timestamps; loop: restart at the end (timestamps and
    indices keep increasing) instead of raising RecordingError.
    """

    def __init__(self, path: str | Path, realtime: bool = False, loop: bool = False) -> None:
        self.recording = FramesRecording(path)
        self.realtime = realtime
        self.loop = loop
        self._next = 0
        self._start_wall: float | None = None

    @property
    def intrinsics(self) -> Intrinsics:
        return self.recording.intrinsics

    @property
    def depth_scale(self) -> float:
        return self.recording.depth_scale

    @property
    def min_range_m(self) -> float | None:
        return self.recording.min_range_m

    def connect(self) -> None:
        self._next = 0
        self._start_wall = None

    def read(self, timeout_s: float = 2.0) -> Frame:
        rec = self.recording
        n = len(rec)
        if n == 0:
            raise RecordingError(f"recording {rec.path} has no frames; record again")
        lap, i = divmod(self._next, n)
        if lap > 0 and not self.loop:
            raise RecordingError(
                f"end of recording {rec.path} after {n} frames; pass loop=True to replay it again"
            )
        try:
            frame = rec.frame(i)
        except RecordingError as exc:  # a damaged frame is a camera failure, not the end of the recording
            raise CameraError(f"replay {rec.path}: frame {i} is damaged: {exc}") from None
        t0, t_last = float(rec.records[0]["t"]), float(rec.records[-1]["t"])
        period = (t_last - t0) * n / (n - 1) if n > 1 else 0.0
        frame.t += lap * period
        frame.index += lap * n
        if self.realtime:
            if self._start_wall is None:
                self._start_wall = time.monotonic()
            time.sleep(max(0.0, self._start_wall + (frame.t - t0) - time.monotonic()))
        self._next += 1
        return frame

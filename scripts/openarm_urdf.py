"""Convert the OpenArm vendor's MJCF (PyPI `openarm-mujoco`, Apache-2.0) into the URDF the project ships.

    python scripts/openarm_urdf.py [--mjcf PATH/openarm_bimanual.xml] [--out drivers/arm/openarm]

One arm of the bimanual model (the right one, `openarm_right_*`) with its gripper, on a pedestal: the URDF's root
link `openarm_pedestal` stands on the floor under the arm's mount, which sits PEDESTAL_HEIGHT_M above it as in the
vendor's pedestal scene (pedestal/pedestal.xml). Bodies become links, hinge joints revolute joints (axis, range and
effort as the vendor gives them; velocity: the motor model's VMAX, which the robot config narrows), inertials and
collision meshes are kept (the collision STL files are copied; they also stand for the visuals, whose OBJ files are
ten times larger). The fingers keep the vendor's hinges, the second mimicking the first. A fixed frame
`openarm_right_tcp` lies between the fingertips' pads (the grasp frame,
z along the approach). The vendor's LICENSE is copied beside the
files and NOTICE says what was changed. Without --mjcf the installed package's data is read
(`pip install openarm-mujoco`); tests/test_openarm.py checks the shipped files equal a fresh conversion.
"""

from __future__ import annotations

import argparse
import shutil
import sysconfig
import xml.etree.ElementTree as ET
from importlib import metadata
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

ARM = "openarm_right_"
PEDESTAL_HEIGHT_M = 0.698  # the vendor's pedestal scene: "arms attach at the pedestal top (z=0.698)"
MOTOR_VMAX = {"motor_DM8009": 45.0, "motor_DM4340": 8.0, "motor_DM4310": 30.0, "motor_finger": 30.0}
TCP_ABOVE_TIP_M = 0.012  # the grasp frame: this far up the pads from the fingertips' lowest point
OUT = Path(__file__).resolve().parents[1] / "drivers" / "arm" / "openarm"


def installed_mjcf() -> Path:
    """openarm_bimanual.xml of the installed `openarm-mujoco` (its data files under the environment's share/,
    found without importing the package: it imports mujoco)."""
    path = Path(sysconfig.get_path("data")) / "share" / "openarm_mujoco" / "v2" / "openarm_bimanual.xml"
    if not path.is_file():
        raise SystemExit(f"{path} not found: `pip install openarm-mujoco`, or give --mjcf")
    return path


def _license(mjcf: Path) -> Path | None:
    """The vendor's LICENSE: the installed distribution's, or the source tree's beside v2/."""
    try:
        for f in metadata.distribution("openarm-mujoco").files or []:
            if f.name == "LICENSE":
                return Path(metadata.distribution("openarm-mujoco").locate_file(f))
    except metadata.PackageNotFoundError:
        pass
    candidate = mjcf.parents[1] / "LICENSE"
    return candidate if candidate.is_file() else None


def _floats(text: str | None, default: str) -> np.ndarray:
    return np.array((text or default).split(), float)


def _origin(parent: ET.Element, pos: np.ndarray, quat_wxyz: np.ndarray) -> None:
    """A URDF <origin> under `parent` for a MuJoCo pos and quaternion (w x y z)."""
    w, x, y, z = quat_wxyz
    rpy = Rotation.from_quat([x, y, z, w]).as_euler("xyz")
    ET.SubElement(parent, "origin", xyz=" ".join(f"{v:.9g}" for v in pos),
                  rpy=" ".join(f"{0.0 if abs(v) < 1e-12 else v:.9g}" for v in rpy))


def _inertial(link: ET.Element, body: ET.Element) -> None:
    inertial = body.find("inertial")
    if inertial is None:
        return
    node = ET.SubElement(link, "inertial")
    _origin(node, _floats(inertial.get("pos"), "0 0 0"), _floats(inertial.get("quat"), "1 0 0 0"))
    ET.SubElement(node, "mass", value=inertial.get("mass"))
    ixx, iyy, izz = _floats(inertial.get("diaginertia"), "0 0 0")
    ET.SubElement(node, "inertia", ixx=f"{ixx:.9g}", iyy=f"{iyy:.9g}", izz=f"{izz:.9g}", ixy="0", ixz="0", iyz="0")


def _meshes(link: ET.Element, body: ET.Element, files: dict[str, str], used: set[str]) -> None:
    """The body's collision mesh geoms as <collision> and <visual> elements (meshes/NAME.stl)."""
    for geom in body.findall("geom"):
        if geom.get("class") not in ("collision", "fingertip") or geom.get("type") != "mesh":
            continue
        source = files[geom.get("mesh")]
        used.add(source)
        for kind in ("collision", "visual"):
            node = ET.SubElement(link, kind, name=geom.get("name") or geom.get("mesh"))
            _origin(node, _floats(geom.get("pos"), "0 0 0"), _floats(geom.get("quat"), "1 0 0 0"))
            geometry = ET.SubElement(node, "geometry")
            ET.SubElement(geometry, "mesh", filename=f"meshes/{Path(source).name}")


def _joint(robot: ET.Element, body: ET.Element, parent: str, mimic: dict[str, str]) -> None:
    joint = body.find("joint")
    name = joint.get("name") if joint is not None else f"{body.get('name')}_fixed"
    node = ET.SubElement(robot, "joint", name=name, type="revolute" if joint is not None else "fixed")
    _origin(node, _floats(body.get("pos"), "0 0 0"), _floats(body.get("quat"), "1 0 0 0"))
    ET.SubElement(node, "parent", link=parent)
    ET.SubElement(node, "child", link=body.get("name"))
    if joint is None:
        return
    ET.SubElement(node, "axis", xyz=" ".join(f"{v:g}" for v in _floats(joint.get("axis"), "0 0 1")))
    lower, upper = _floats(joint.get("range"), "0 0")
    effort = max(abs(_floats(joint.get("actuatorfrcrange"), "0 0")))
    ET.SubElement(node, "limit", lower=f"{lower:g}", upper=f"{upper:g}", effort=f"{effort:g}",
                  velocity=f"{MOTOR_VMAX[joint.get('class')]:g}")
    if name in mimic:
        ET.SubElement(node, "mimic", joint=mimic[name], multiplier="1", offset="0")


def _tcp(robot: ET.Element, hand: ET.Element, mjcf_dir: Path, files: dict[str, str]) -> None:
    """The grasp frame: midway between the fingers, TCP_ABOVE_TIP_M above their lowest point (closed fingers), turned
    as every grasp frame of the project is: z along the approach (out of the fingertips), x along the pads' width
    (a bar's length), the fingers closing along y."""
    lowest = np.inf
    for finger in hand.findall("body"):
        offset = _floats(finger.get("pos"), "0 0 0")
        for geom in finger.findall("geom"):
            if geom.get("class") == "fingertip":
                mesh = _stl_vertices(mjcf_dir / "assets" / files[geom.get("mesh")])
                lowest = min(lowest, offset[2] + mesh[:, 2].min())
    node = ET.SubElement(robot, "joint", name=f"{ARM}tcp_joint", type="fixed")
    _origin(node, np.array([0.0, 0.0, round(lowest + TCP_ABOVE_TIP_M, 4)]), np.array([0.0, 1.0, 0, 0]))
    ET.SubElement(node, "parent", link=hand.get("name"))
    ET.SubElement(node, "child", link=f"{ARM}tcp")
    _massless(ET.SubElement(robot, "link", name=f"{ARM}tcp"))


def _massless(link: ET.Element) -> None:
    """A frame link: a negligible inertial (simulators give a link without one a mass of 1 kg)."""
    node = ET.SubElement(link, "inertial")
    ET.SubElement(node, "mass", value="1e-6")
    ET.SubElement(node, "inertia", ixx="1e-9", iyy="1e-9", izz="1e-9", ixy="0", ixz="0", iyz="0")


def _stl_vertices(path: Path) -> np.ndarray:
    """The vertices of a binary STL file (m)."""
    data = path.read_bytes()
    count = int.from_bytes(data[80:84], "little")
    records = np.frombuffer(data, dtype=np.dtype([("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]),
                            count=count, offset=84)
    return records["v"].reshape(-1, 3).astype(float)


def convert(mjcf: Path, out: Path) -> Path:
    """Write openarm.urdf, meshes/, LICENSE and NOTICE into `out`; the URDF's path."""
    root = ET.parse(mjcf).getroot()
    files = {m.get("name"): m.get("file") for m in root.iter("mesh")}
    mimic = {e.get("joint2"): e.get("joint1") for e in root.iter("joint") if e.get("joint2")}
    robot = ET.Element("robot", name="openarm")
    _massless(ET.SubElement(robot, "link", name="openarm_pedestal"))
    base = next(b for b in root.iter("body") if b.get("name") == f"{ARM}base_link")
    # the mount at the pedestal's height, placed so that the arm hangs over the pedestal's origin (its first two
    # links reach sideways from the mount)
    reach_y = sum(_floats(b.get("pos"), "0 0 0")[1] for b in (base.find("body"), base.find("body").find("body")))
    base.set("pos", f"0 {-reach_y:.9g} {PEDESTAL_HEIGHT_M}")
    used: set[str] = set()
    hand = None
    stack = [(base, "openarm_pedestal")]
    while stack:
        body, parent = stack.pop(0)
        link = ET.SubElement(robot, "link", name=body.get("name"))
        _inertial(link, body)
        _meshes(link, body, files, used)
        _joint(robot, body, parent, mimic)
        if body.get("name") == f"{ARM}ee_base_link":
            hand = body
        stack.extend((child, body.get("name")) for child in body.findall("body"))
    _tcp(robot, hand, mjcf.parent, files)
    ET.indent(robot)
    out.mkdir(parents=True, exist_ok=True)
    (out / "meshes").mkdir(exist_ok=True)
    for source in sorted(used):
        shutil.copyfile(mjcf.parent / "assets" / source, out / "meshes" / Path(source).name)
    urdf = out / "openarm.urdf"
    urdf.write_text('<?xml version="1.0"?>\n<!-- Generated by scripts/openarm_urdf.py from openarm-mujoco '
                    f'{_version()} (Apache-2.0, see LICENSE and NOTICE beside this file) -->\n'
                    + ET.tostring(robot, encoding="unicode") + "\n")
    license_file = _license(mjcf)
    if license_file is None:
        raise SystemExit("the vendor's LICENSE was not found: the converted files must keep it")
    shutil.copyfile(license_file, out / "LICENSE")
    (out / "NOTICE").write_text(NOTICE.format(version=_version()))
    return urdf


def _version() -> str:
    try:
        return metadata.version("openarm-mujoco")
    except metadata.PackageNotFoundError:
        return "(source tree)"


NOTICE = """OpenArm robot description
Copyright 2026 Enactic, Inc. Licensed under the Apache License, Version 2.0 (LICENSE in this folder).

openarm.urdf and meshes/ are derived from openarm-mujoco {version} (v2/openarm_bimanual.xml and
v2/assets/collision/*.stl) by scripts/openarm_urdf.py of axisloop. Changes: only the right arm and its
gripper are kept; MJCF bodies, hinge joints, inertials and collision meshes are written as URDF links, revolute
joints, inertials and collision (and visual) meshes; the arm stands on a pedestal link at the vendor's pedestal
height; joint velocity limits are the motors' VMAX; a grasp frame between the fingertips is added. The STL files
are copied unchanged.
"""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--mjcf", type=Path, help="openarm_bimanual.xml (default: the installed openarm-mujoco's)")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args()
    print(convert(args.mjcf or installed_mjcf(), args.out))


if __name__ == "__main__":
    main()

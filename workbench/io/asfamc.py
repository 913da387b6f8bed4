"""CMU / Acclaim ASF (skeleton) and AMC (motion) reading.

The ASF model: every bone has a rest ``direction`` (a unit vector in world axes, used
as written, not renormalised: the bone vector is ``direction * length``), a
``length``, an ``axis`` ``ax ay az ORDER`` giving its local frame C (the three numbers are
the angles about the axes named by ORDER, applied in that order: ``XYZ`` means
``C = Rz(az) Ry(ay) Rx(ax)`` on column vectors) and ``dof`` (a subset of ``rx ry rz``).
Per frame the AMC gives the root ``TX TY TZ RX RY RZ`` (in the root's ``order``) and each
bone's dof values, applied in the listed order (``rx ry rz``: ``M = Rz Ry Rx``, rx
first). The bone's rotation relative to its parent, in world-aligned rest axes, is
``L = C M C^-1`` (the root uses its ``orientation``/``axis`` as C), and a bone starts at
the END of its parent bone. This is the convention of the CMU AMC viewer.

Mapping onto :class:`Skeleton`: one joint per ASF bone, plus ``root`` first, in
depth-first ``:hierarchy`` order, with the ASF names (``CMU_ASF_TO_BVH`` maps them to the
cgspeed BVH names; for the CMU tree the joint order is the BVH's). A joint's offset is
its parent bone's ``direction * length`` (zero for the root and its children); leaf
bones get an End Site at their own ``direction * length``. Zero angles give the ASF rest
pose. Every joint gets BVH-style channels ``Zrotation Yrotation Xrotation`` (root:
``Xposition Yposition Zposition`` first); the angles are ``L`` as ZYX Euler angles in
degrees, kept continuous in time. For a bone with C = I and dof ``rx ry rz`` they equal
``(rz, ry, rx)`` of the AMC. Bones without dofs get zero angles.

Units: lengths and root positions stay in the file's unit. ASF ``:units length s``
means the file's lengths are inches scaled by s (CMU uses s = 0.45), so
``unit_cm = 2.54 / s`` (5.644 cm for CMU, the same unit as the cgspeed BVH files); with
no ``length`` the unit is guessed from the rest height. Angles are in degrees unless the
ASF says ``angle rad`` (or the AMC ``:RADIANS``). The ASF root ``position`` is ignored:
the AMC root translation is absolute. AMC files do not store a frame rate: ``fps``
defaults to 120 (CMU's rate). Every problem is a :class:`MotionFileError` naming the
file and line.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.motion import Motion
from ..core.rotations import axis_rotation, matrix_to_euler, nearest_euler
from ..core.skeleton import Skeleton
from .errors import MotionFileError
from .limits import MAX_ABS_VALUE, MAX_JOINTS, name_fault, read_lines

#: ASF bone names of the CMU skeleton -> joint names of the cgspeed BVH conversion
#: (same tree and joint order; the hip joints and clavicles are the BVH's fixed
#: branch points LHipJoint/RHipJoint and LeftShoulder/RightShoulder).
CMU_ASF_TO_BVH: dict[str, str] = {
    "root": "Hips",
    "lhipjoint": "LHipJoint",
    "lfemur": "LeftUpLeg",
    "ltibia": "LeftLeg",
    "lfoot": "LeftFoot",
    "ltoes": "LeftToeBase",
    "rhipjoint": "RHipJoint",
    "rfemur": "RightUpLeg",
    "rtibia": "RightLeg",
    "rfoot": "RightFoot",
    "rtoes": "RightToeBase",
    "lowerback": "LowerBack",
    "upperback": "Spine",
    "thorax": "Spine1",
    "lowerneck": "Neck",
    "upperneck": "Neck1",
    "head": "Head",
    "lclavicle": "LeftShoulder",
    "lhumerus": "LeftArm",
    "lradius": "LeftForeArm",
    "lwrist": "LeftHand",
    "lhand": "LeftFingerBase",
    "lfingers": "LeftHandIndex1",
    "lthumb": "LThumb",
    "rclavicle": "RightShoulder",
    "rhumerus": "RightArm",
    "rradius": "RightForeArm",
    "rwrist": "RightHand",
    "rhand": "RightFingerBase",
    "rfingers": "RightHandIndex1",
    "rthumb": "RThumb",
}

ROOT_CHANNELS = ("Xposition", "Yposition", "Zposition", "Zrotation", "Yrotation", "Xrotation")
JOINT_CHANNELS = ("Zrotation", "Yrotation", "Xrotation")
EULER_ORDER = "ZYX"
INCH_CM = 2.54

_AXIS = {"x": 0, "y": 1, "z": 2}
_ROOT_TOKENS = ("TX", "TY", "TZ", "RX", "RY", "RZ")
_BONE_KEYS_IGNORED = {"id", "limits", "bodymass", "cofmass"}


@dataclass
class _Bone:
    name: str
    line: int  # line of its 'begin'
    direction: np.ndarray | None = None
    length: float | None = None
    axis: tuple[np.ndarray, str] | None = None  # (angles in file unit, order)
    dofs: tuple[str, ...] = ()
    children: list[str] = field(default_factory=list)
    parent: str | None = None


@dataclass(frozen=True)
class AsfModel:
    """A parsed ASF: the Skeleton plus what reading an AMC needs.

    ``frames`` (J, 3, 3): each joint's C; ``dofs``: per joint the rotation dofs (``"rx"``,
    ...; for the root the ``order`` tokens, lower case, positions included);
    ``angle_scale``: file angle unit -> radians.
    """

    path: str
    skeleton: Skeleton
    frames: np.ndarray
    dofs: tuple[tuple[str, ...], ...]
    angle_scale: float


# -- helpers --------------------------------------------------------------------------
def _numbers(words: list[str], count: int, what: str, path: Path, line: int) -> np.ndarray:
    if len(words) < count:
        raise MotionFileError(path, f"{what} needs {count} numbers, found {len(words)}", line)
    try:
        values = np.array([float(w) for w in words[:count]])
    except ValueError:
        bad = next(w for w in words[:count] if not _is_float(w))
        raise MotionFileError(path, f"{what}: {bad!r} is not a number", line) from None
    if not np.isfinite(values).all():
        raise MotionFileError(path, f"{what}: values must be finite, found {' '.join(words[:count])}", line)
    return values


def _is_float(word: str) -> bool:
    try:
        float(word)
    except ValueError:
        return False
    return True


def _rotation_from(angles_rad: np.ndarray, axes: str) -> np.ndarray:
    """Rotation (..., 3, 3) applying ``angles_rad[..., i]`` about ``axes[i]`` first to last
    (``"xyz"``: Rz @ Ry @ Rx)."""
    angles_rad = np.asarray(angles_rad, float)
    R = np.broadcast_to(np.eye(3), angles_rad.shape[:-1] + (3, 3))
    for i, a in enumerate(axes.lower()):
        R = axis_rotation(_AXIS[a], angles_rad[..., i]) @ R
    return R


# -- ASF ------------------------------------------------------------------------------
def _parse_asf(path: Path) -> AsfModel:
    lines = read_lines(path)
    section = None
    length_scale: float | None = None
    angle_scale = np.pi / 180.0
    root_order: tuple[str, ...] = _ROOT_TOKENS
    root_axis = "XYZ"
    root_orientation = np.zeros(3)
    bones: dict[str, _Bone] = {}
    current: _Bone | None = None
    seen: set[str] = set()
    root_children: list[str] = []
    hierarchy_open = False
    hierarchy_line = None
    last_line = max(len(lines), 1)

    def fail(message: str, line: int) -> None:
        raise MotionFileError(path, message, line)

    for n, raw in enumerate(lines, start=1):
        text = raw.split("#", 1)[0].strip()
        if not text:
            continue
        words = text.split()
        key = words[0]
        if key.startswith(":"):
            if current is not None:
                fail(f"bone block starting at line {current.line} has no 'end'", n)
            if section == ":hierarchy" and hierarchy_open:
                fail("the :hierarchy section has no 'end'", n)
            section = key.lower()
            seen.add(section)
            if section == ":hierarchy":
                hierarchy_line = n
            rest = words[1:]
            if section in (":bonedata", ":hierarchy", ":units", ":root") and rest:
                fail(f"unexpected {rest[0]!r} after {key}", n)
            continue
        if section == ":units":
            kind = key.lower()
            if kind == "length":
                value = _numbers(words[1:], 1, "':units length'", path, n)[0]
                if value <= 0:
                    fail(f"':units length' must be positive, found {words[1]}", n)
                length_scale = float(value)
            elif kind == "angle":
                unit = words[1].lower() if len(words) > 1 else ""
                if unit.startswith("deg"):
                    angle_scale = np.pi / 180.0
                elif unit.startswith("rad"):
                    angle_scale = 1.0
                else:
                    fail(f"':units angle' must be 'deg' or 'rad', found {unit!r}", n)
        elif section == ":root":
            kind = key.lower()
            if kind == "order":
                tokens = tuple(w.upper() for w in words[1:])
                bad = [t for t in tokens if t not in _ROOT_TOKENS]
                if bad or len(set(tokens)) != len(tokens):
                    fail(
                        f"root 'order' must list distinct tokens of {' '.join(_ROOT_TOKENS)}, "
                        f"found {' '.join(words[1:])}",
                        n,
                    )
                root_order = tokens
            elif kind == "axis":
                order = words[1].upper() if len(words) > 1 else ""
                if sorted(order) != ["X", "Y", "Z"]:
                    fail(f"root 'axis' must be a permutation of XYZ, found {order!r}", n)
                root_axis = order
            elif kind == "orientation":
                root_orientation = _numbers(words[1:], 3, "root 'orientation'", path, n)
            elif kind == "position":
                _numbers(words[1:], 3, "root 'position'", path, n)
            else:
                fail(f":root: unknown keyword {key!r}", n)
        elif section == ":bonedata":
            kind = key.lower()
            if kind == "begin":
                if current is not None:
                    fail(f"bone block starting at line {current.line} has no 'end'", n)
                current = _Bone(name="", line=n)
                continue
            if current is None:
                fail(f"expected 'begin' in :bonedata, found {key!r}", n)
            if kind == "end":
                _finish_bone(current, bones, path)
                current = None
            elif kind == "name":
                if len(words) != 2:
                    fail("'name' needs exactly one bone name", n)
                if (fault := name_fault(words[1])) is not None:
                    fail(f"bone name {words[1]!r} {fault}", n)
                current.name = words[1]
            elif kind == "direction":
                current.direction = _numbers(words[1:], 3, f"bone {current.name!r} 'direction'", path, n)
            elif kind == "length":
                current.length = float(_numbers(words[1:], 1, f"bone {current.name!r} 'length'", path, n)[0])
                if current.length < 0:
                    fail(f"bone {current.name!r}: negative length {words[1]}", n)
            elif kind == "axis":
                angles = _numbers(words[1:], 3, f"bone {current.name!r} 'axis'", path, n)
                order = words[4].upper() if len(words) > 4 else "XYZ"
                if sorted(order) != ["X", "Y", "Z"]:
                    fail(f"bone {current.name!r}: axis order must be a permutation of XYZ, found {order!r}", n)
                current.axis = (angles, order)
            elif kind == "dof":
                dofs = tuple(w.lower() for w in words[1:])
                trans = [d for d in dofs if d in ("tx", "ty", "tz", "l")]
                if trans:
                    fail(f"bone {current.name!r}: translation dof {trans[0]!r} is not supported", n)
                if any(d not in ("rx", "ry", "rz") for d in dofs) or len(set(dofs)) != len(dofs):
                    fail(f"bone {current.name!r}: dof must list distinct rx, ry, rz, found {' '.join(words[1:])}", n)
                current.dofs = dofs
            elif kind in _BONE_KEYS_IGNORED or key.startswith("("):
                pass  # limits and their continuation lines, ids, masses
            else:
                fail(f"bone {current.name or '?'}: unknown keyword {key!r}", n)
        elif section == ":hierarchy":
            kind = key.lower()
            if kind == "begin":
                hierarchy_open = True
                continue
            if kind == "end":
                hierarchy_open = False
                continue
            if not hierarchy_open:
                fail(f"expected 'begin' in :hierarchy, found {key!r}", n)
            for name in words:
                if name != "root" and name not in bones:
                    fail(f":hierarchy names {name!r}, which is not a bone in :bonedata", n)
            parent = key
            for child in words[1:]:
                if child == "root":
                    fail("the root cannot be a child in :hierarchy", n)
                bone = bones[child]
                if bone.parent is not None:
                    fail(f"bone {child!r} is given a second parent ({parent!r}, already {bone.parent!r})", n)
                if child == parent:
                    fail(f"bone {child!r} is its own parent", n)
                bone.parent = parent
            (root_children if parent == "root" else bones[parent].children).extend(words[1:])

    if current is not None:
        fail(f"bone block starting at line {current.line} has no 'end'", last_line)
    if hierarchy_open:
        fail("the :hierarchy section has no 'end'", last_line)
    if ":bonedata" not in seen:
        fail("no :bonedata section", last_line)
    if ":hierarchy" not in seen:
        fail("no :hierarchy section", last_line)
    if not bones:
        fail("the :bonedata section defines no bones", last_line)
    if not root_children:
        fail("the :hierarchy gives the root no children", hierarchy_line or last_line)
    for bone in bones.values():
        if bone.parent is None:
            fail(f"bone {bone.name!r} is not attached in :hierarchy", bone.line)

    # Depth-first order from the root (the hierarchy's child order).
    order: list[str] = []
    parents: list[int] = []
    stack = [(c, 0) for c in reversed(root_children)]
    while stack:
        name, p = stack.pop()
        order.append(name)
        parents.append(p)
        idx = len(order)  # index of this joint (root is 0)
        stack.extend((c, idx) for c in reversed(bones[name].children))
    if len(order) != len(bones):
        lost = next(b for b in bones.values() if b.name not in set(order))
        fail(f"bone {lost.name!r} is not connected to the root (a cycle in :hierarchy)", lost.line)

    names = ("root",) + tuple(order)
    vectors = {name: bones[name].direction * bones[name].length for name in order}
    offsets = np.zeros((len(names), 3))
    end_sites = []
    frames = np.empty((len(names), 3, 3))
    frames[0] = _rotation_from(root_orientation * angle_scale, root_axis)
    dofs: list[tuple[str, ...]] = [tuple(t.lower() for t in root_order)]
    for j, name in enumerate(order, start=1):
        p = parents[j - 1]
        if p > 0:
            offsets[j] = vectors[names[p]]
        bone = bones[name]
        if not bone.children:
            end_sites.append((j, tuple(float(v) for v in vectors[name])))
        angles, axis_order = bone.axis
        frames[j] = _rotation_from(angles * angle_scale, axis_order)
        dofs.append(bone.dofs)
    unit_cm = INCH_CM / length_scale if length_scale is not None else 0.0
    skeleton = Skeleton(
        names,
        (-1,) + tuple(parents),
        offsets,
        (ROOT_CHANNELS,) + (JOINT_CHANNELS,) * len(order),
        tuple(end_sites),
        unit_cm,
    )
    return AsfModel(str(path), skeleton, frames, tuple(dofs), float(angle_scale))


def _finish_bone(bone: _Bone, bones: dict[str, _Bone], path: Path) -> None:
    where = f"bone block starting at line {bone.line}"
    if not bone.name:
        raise MotionFileError(path, f"{where} has no 'name'", bone.line)
    if bone.name == "root":
        raise MotionFileError(path, f"{where}: 'root' is reserved for the :root section", bone.line)
    if bone.name in bones:
        raise MotionFileError(path, f"bone name {bone.name!r} appears twice", bone.line)
    if len(bones) + 1 >= MAX_JOINTS:  # the root is a joint too
        raise MotionFileError(
            path, f"more than {MAX_JOINTS:,} joints with the root: no capture skeleton has so many", bone.line
        )
    for key in ("direction", "length", "axis"):
        if getattr(bone, key) is None:
            raise MotionFileError(path, f"bone {bone.name!r} ({where}) has no '{key}'", bone.line)
    if bone.length > 0 and float(np.linalg.norm(bone.direction)) < 1e-12:
        raise MotionFileError(path, f"bone {bone.name!r} has a zero 'direction'", bone.line)
    bones[bone.name] = bone


def read_asf(path: str | Path) -> Skeleton:
    """Read an ASF skeleton (see the module docstring for the mapping)."""
    return _parse_asf(Path(path)).skeleton


# -- AMC ------------------------------------------------------------------------------
def find_asf(amc_path: str | Path) -> Path:
    """The ASF for an AMC file: in the same folder, the one whose stem is the AMC's
    subject prefix (``11_01.amc`` -> ``11.asf``), else the only ASF there."""
    amc_path = Path(amc_path)
    folder = amc_path.parent
    try:
        candidates = sorted(p for p in folder.iterdir() if p.suffix.lower() == ".asf" and p.is_file())
    except OSError as err:
        raise MotionFileError(amc_path, f"cannot look for its .asf skeleton ({err.strerror or err})") from None
    subject = amc_path.stem.split("_")[0].lower()
    for p in candidates:
        if p.stem.lower() == subject:
            return p
    if len(candidates) == 1:
        return candidates[0]
    if not candidates:
        raise MotionFileError(
            amc_path, f"no .asf skeleton file in {str(folder)!r}: put the take's skeleton ({subject}.asf) beside it"
        )
    raise MotionFileError(
        amc_path,
        f"{len(candidates)} .asf files in {str(folder)!r} and none is named {subject}.asf: name the take's "
        f"skeleton {subject}.asf",
    )


def read_amc(path: str | Path, asf_path: str | Path | None = None, *, fps: float = 120.0) -> Motion:
    """Read a CMU AMC motion with its ASF skeleton into a Motion.

    ``asf_path`` defaults to :func:`find_asf`. AMC files carry no frame rate: ``fps``
    (default 120, CMU's capture rate) sets it. Raises :class:`MotionFileError`.
    """
    path = Path(path)
    lines = read_lines(path)
    model = _parse_asf(find_asf(path) if asf_path is None else Path(asf_path))
    values, angle_scale = _parse_amc(lines, model, path)
    root, angles = _convert(model, values, angle_scale)
    return Motion(model.skeleton, fps, root, angles, name=path.stem)


def _parse_amc(lines: list[str], model: AsfModel, path: Path) -> tuple[list[np.ndarray], float]:
    """Per joint an (F, n_dof) array of the file's values (dofs in the ASF's order), and
    the angle scale (file unit -> radians)."""
    names = model.skeleton.names
    index = {name: j for j, name in enumerate(names)}
    counts = [len(d) for d in model.dofs]
    needed = [j for j, c in enumerate(counts) if c > 0]
    tokens: list[list[list[str]]] = [[] for _ in names]
    where: list[list[int]] = [[] for _ in names]
    angle_scale = model.angle_scale
    frame_line = None
    frame_number = None
    frame_count = 0
    present: set[int] = set()

    def close_frame(end_line: int) -> None:
        missing = [names[j] for j in needed if j not in present]
        if missing:
            raise MotionFileError(
                path,
                f"frame {frame_number} (line {frame_line}) has no values for {', '.join(missing[:5])}"
                + (f" and {len(missing) - 5} more bones" if len(missing) > 5 else ""),
                end_line,
            )

    for n, raw in enumerate(lines, start=1):
        text = raw.strip()
        if not text or text.startswith("#"):
            continue
        if text.startswith(":"):
            word = text.split()[0].upper()
            if frame_line is not None:
                raise MotionFileError(path, f"unexpected {word} after the first frame", n)
            if word == ":DEGREES":
                angle_scale = np.pi / 180.0
            elif word == ":RADIANS":
                angle_scale = 1.0
            continue
        words = text.split()
        name = words[0]
        if len(words) == 1 and name not in index:
            try:
                number = int(name)
            except ValueError:
                raise MotionFileError(path, f"expected a frame number or a bone line, found {name!r}", n) from None
            if frame_line is not None:
                close_frame(n - 1)
                if number != frame_number + 1:
                    raise MotionFileError(path, f"frame number {number} does not follow {frame_number}", n)
            frame_line, frame_number = n, number
            frame_count += 1
            present = set()
            continue
        j = index.get(name)
        if j is None:
            raise MotionFileError(path, f"unknown bone {name!r} (not in {Path(model.path).name})", n)
        if frame_line is None:
            raise MotionFileError(path, f"bone line for {name!r} before the first frame number", n)
        if len(words) - 1 != counts[j]:
            raise MotionFileError(
                path, f"frame {frame_number}: bone {name!r} has {len(words) - 1} values, its dof needs {counts[j]}", n
            )
        if j in present:
            raise MotionFileError(path, f"frame {frame_number}: bone {name!r} appears twice", n)
        present.add(j)
        if counts[j]:
            tokens[j].append(words[1:])
            where[j].append(n)

    if frame_line is None:
        raise MotionFileError(path, "the file has no frames", max(len(lines), 1))
    close_frame(len(lines))

    values = []
    for j in range(len(names)):
        if not counts[j]:
            values.append(np.zeros((frame_count, 0)))
            continue
        try:
            arr = np.array(tokens[j], dtype=float)
        except ValueError:
            for row, n in zip(tokens[j], where[j]):
                for w in row:
                    if not _is_float(w):
                        raise MotionFileError(path, f"bone {names[j]!r}: {w!r} is not a number", n) from None
            raise
        with np.errstate(invalid="ignore"):
            bad = ~(np.abs(arr) <= MAX_ABS_VALUE)  # NaN, infinite or absurd
        if bad.any():
            r, c = (int(i) for i in np.argwhere(bad)[0])
            raise MotionFileError(
                path,
                f"bone {names[j]!r}: {arr[r, c]:g} is no position or angle (an AMC marks no value missing: "
                f"each lies within +-{MAX_ABS_VALUE:g}); mend the line or cut the take before it",
                where[j][r],
            )
        values.append(arr)
    return values, angle_scale


def _convert(model: AsfModel, values: list[np.ndarray], angle_scale: float) -> tuple[np.ndarray, np.ndarray]:
    """Root positions (F, 3) and ZYX Euler angles (F, J, 3) in degrees."""
    F, J = values[0].shape[0], len(values)
    L = np.empty((F, J, 3, 3))
    root = np.zeros((F, 3))
    for j, (dofs, v) in enumerate(zip(model.dofs, values)):
        rot = [(k, d[1]) for k, d in enumerate(dofs) if d[0] == "r"]
        for k, d in enumerate(dofs):
            if d[0] == "t":
                root[:, _AXIS[d[1]]] = v[:, k]
        M = _rotation_from(v[:, [k for k, _ in rot]] * angle_scale, "".join(a for _, a in rot))
        C = model.frames[j]
        L[:, j] = C @ M @ C.T
    angles = matrix_to_euler(L, EULER_ORDER)
    angles[np.abs(angles) < 1e-12] = 0.0
    for f in range(1, F):
        angles[f] = nearest_euler(angles[f], angles[f - 1])
    return root, angles

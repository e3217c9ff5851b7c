"""Blender's own BVH importer as a reference reader (run by tests/test_bvh_readers.py, not by pytest).

    blender -b --factory-startup --python tests/blender_bvh_positions.py -- OUT.json A.bvh [B.bvh ...]

Imports each file with Blender's add-on `io_anim_bvh` (identity axis conversion, scale 1, one
Blender frame per BVH frame) and writes, for every file, the world position of every bone's head
on every frame: {path: {"names": [J], "positions": (T, J, 3) nested lists}}.  One Blender process
serves all the files (Blender takes seconds to start).
"""

import builtins
import json
import sys

_open = builtins.open


def _open_without_u(file, mode="r", *args, **kwargs):
    # Debian's Blender 3.4 importer calls open(path, 'rU'); Python 3.11 removed the 'U' mode (it was a no-op).
    if isinstance(mode, str):
        mode = mode.replace("U", "")
    return _open(file, mode, *args, **kwargs)


builtins.open = _open_without_u

import bpy  # noqa: E402  (after the patch: the add-on's module is imported inside Blender)
from io_anim_bvh import import_bvh  # noqa: E402
from mathutils import Matrix  # noqa: E402


def bone_heads(path: str) -> dict:
    """One file -> {"names": bone names, "positions": (T, J, 3)} world head positions per frame."""
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    scene = bpy.context.scene
    before = set(bpy.data.objects)
    import_bvh.load(bpy.context, path, global_matrix=Matrix.Identity(4), rotate_mode="NATIVE", frame_start=1,
                    use_fps_scale=False, update_scene_fps=False, update_scene_duration=False)
    (arm,) = [o for o in bpy.data.objects if o not in before and o.type == "ARMATURE"]
    frames = int(open(path).read().split("Frames:")[1].split()[0])
    names = [b.name for b in arm.pose.bones]
    positions = []
    for t in range(frames):
        scene.frame_set(1 + t)
        positions.append([list(arm.matrix_world @ arm.pose.bones[n].head) for n in names])
    return {"names": names, "positions": positions}


def main() -> None:
    argv = sys.argv[sys.argv.index("--") + 1:]
    out, paths = argv[0], argv[1:]
    result = {p: bone_heads(p) for p in paths}
    with _open(out, "w") as f:
        json.dump(result, f)


main()

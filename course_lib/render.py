"""Pictures of motion: 3-D renders with pyvista and 2-D stick figures with scikit-image.

Everything accepts either a `Motion` (uses `positions()`, `skeleton.parents`,
`skeleton.names` and `contacts()`) or raw joint positions `(J, 3)` / `(T, J, 3)`
in metres plus a `parents` array.  Conventions of the course: Y up, the
character faces +Z at rest, so its left (+X) appears on the image's right when
seen from the front.  Image sizes are always `size=(H, W)` in pixels; every
function returns `(H, W, 3)` uint8 arrays (GIFs are returned as bytes).

3-D (pyvista, needs OpenGL): `render_frame`, `render_still`, `render_side_by_side`, `render_keyframes`
(poses in place, floor lines), and animations:
`render_mp4` (H.264, shown with `video_html`: a player with play and scrub controls), `render_gif`
(only where no player can be used).  Bones are tubes, joints spheres, on a checkered floor
with 0.5 m tiles; optional root trajectory and discs under feet in contact.
Headless machines must set, before Python starts (the Makefile and CI do):

    VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow PYVISTA_OFF_SCREEN=true

This module sets no environment variable and imports pyvista only inside the
3-D functions; every Plotter is created with `off_screen=True`.

2-D (scikit-image, no GL): `stick_figure`, `stick_strip`, `stick_mp4` (`stick_gif`) draw
anti-aliased lines (`skimage.draw.line_aa`) and joint disks; left limbs blue,
right limbs red, the spine grey.  `show(img)` displays an image with matplotlib
(or a GIF's bytes with IPython), never with pyvista's notebook widgets.

Taught in notebooks/00_skeletons_and_rotations.ipynb; used by every lesson.
"""

from __future__ import annotations

import contextlib
import io
import warnings
from dataclasses import dataclass, replace

import numpy as np

from course_lib.outputs import check_outputs

GT_COLOR = (0.12, 0.47, 0.71)  # ground truth: matplotlib's tab:blue
GEN_COLOR = (1.0, 0.50, 0.05)  # generated: tab:orange
DEFAULT_COLORS = (GT_COLOR, GEN_COLOR, (0.17, 0.63, 0.17), (0.84, 0.15, 0.16), (0.58, 0.40, 0.74))
STICK_COLORS = {"left": (0.12, 0.47, 0.71), "right": (0.84, 0.15, 0.16), "centre": (0.3, 0.3, 0.3)}
CANONICAL_FEET = (3, 4, 7, 8)  # LeftFoot, LeftToeBase, RightFoot, RightToeBase of Skeleton.canonical()

# Camera directions (from the look-at point towards the camera), Y up.  "side" looks
# from the character's right (-X) so that walking along +Z goes left to right.
VIEWS_3D = {"side": (-1.0, 0.3, 0.0), "front": (0.0, 0.3, 1.0), "three_quarter": (-1.0, 0.45, 1.2)}
# 2-D views: (world axis drawn to the image's right, world axis drawn up).
VIEWS_2D = {
    "front": ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0)),  # looking at the character's face: its left is on the right
    "side": ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0)),  # from its right side: forward (+Z) is to the right
    "top": ((-1.0, 0.0, 0.0), (0.0, 0.0, 1.0)),  # from above, forward up the image
}
TILE = 0.5  # floor tile / tick spacing, metres


# ----------------------------------------------------------------------------- input checks

@dataclass
class Clip:
    """positions (T, J, 3) metres, parents (J,), optional contacts (T, 2) bool, feet (4,), names, fps."""

    positions: np.ndarray
    parents: tuple[int, ...]
    contacts: np.ndarray | None = None
    feet: tuple[int, ...] | None = None
    names: tuple[str, ...] | None = None
    fps: float | None = None


def as_clip(x, parents=None, contacts=None) -> Clip:
    """A Motion, or positions (J, 3) / (T, J, 3) with parents (J,) -> Clip; raises ValueError on bad input."""
    from course_lib.motion import Motion

    if isinstance(x, Clip):
        return x
    if isinstance(x, Motion):
        sk = x.skeleton
        return Clip(x.positions(), sk.parents, x.contacts(), sk.feet, sk.names, float(x.fps))
    pos = np.asarray(x, dtype=np.float64)
    if pos.ndim == 2:
        pos = pos[None]
    if pos.ndim != 3 or pos.shape[-1] != 3 or pos.shape[0] == 0:
        raise ValueError(f"render: positions must be (J, 3) or (T, J, 3) with T >= 1, got shape {np.shape(x)}")
    if parents is None:
        raise ValueError("render: `parents` is required with raw positions (or pass a Motion)")
    parents = tuple(int(p) for p in parents)
    J = pos.shape[1]
    if len(parents) != J:
        raise ValueError(f"render: {len(parents)} parents for {J} joints in positions of shape {pos.shape}")
    if any(not (-1 <= p < J) or p == j for j, p in enumerate(parents)):
        raise ValueError(f"render: parents must be joint indices in [-1, {J}) other than the joint itself")
    bad = np.argwhere(~np.isfinite(pos).all(-1))
    if len(bad):
        raise ValueError(f"render: positions contain NaN or inf (first at frame {bad[0, 0]}, joint {bad[0, 1]})")
    if contacts is not None:
        contacts = np.asarray(contacts, dtype=bool).reshape(pos.shape[0], 2)
    return Clip(pos, parents, contacts, CANONICAL_FEET if J == 21 else None, None, None)


def _frame_index(clip: Clip, frame: int) -> int:
    T = len(clip.positions)
    if not -T <= frame < T:
        raise IndexError(f"render: frame {frame} out of range for a clip of {T} frames")
    return frame % T


def _bones(parents) -> list[tuple[int, int]]:
    return [(p, j) for j, p in enumerate(parents) if p >= 0]


def _sides(clip: Clip) -> list[str]:
    """'left' | 'right' | 'centre' for each joint, from names (canonical names for a 21-joint clip)."""
    names = clip.names
    if names is None and len(clip.parents) == 21:
        from course_lib.skeleton import CANONICAL_JOINTS
        names = CANONICAL_JOINTS
    if names is None:
        return ["centre"] * len(clip.parents)
    return ["left" if n.startswith("Left") else "right" if n.startswith("Right") else "centre" for n in names]


def _rgb(color) -> np.ndarray:
    """A colour as 0..1 floats or a matplotlib name -> (3,) float."""
    if isinstance(color, str):
        from matplotlib.colors import to_rgb
        color = to_rgb(color)
    return np.clip(np.asarray(color, dtype=np.float64)[:3], 0.0, 1.0)


# ----------------------------------------------------------------------------- 3-D character mesh

def _tube_template(n: int = 14) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Open unit cylinder along +Z from z=0 to z=1: points (2n, 3), normals (2n, 3), faces (n, 5)."""
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a), np.zeros(n)], -1)
    pts = np.concatenate([ring, ring + [0, 0, 1]])
    i = np.arange(n)
    faces = np.stack([np.full(n, 4), i, (i + 1) % n, (i + 1) % n + n, i + n], -1)
    return pts, pts * [1, 1, 0], faces


class _Character:
    """One skeleton as a single PolyData (tubes + spheres) whose points are rewritten per frame."""

    def __init__(self, parents, sides, color, bone_radius: float, joint_radius: float):
        import pyvista as pv

        self.bones = np.array(_bones(parents), dtype=int).reshape(-1, 2)
        self.rb, self.rj = bone_radius, joint_radius
        self.tube_pts, self.tube_nrm, tube_faces = _tube_template()
        sphere = pv.Sphere(radius=1.0, theta_resolution=14, phi_resolution=10)
        self.sph_pts = np.asarray(sphere.points, dtype=np.float64)
        sph_faces = sphere.faces.reshape(-1, 4)
        B, J, nt, ns = len(self.bones), len(parents), len(self.tube_pts), len(self.sph_pts)
        faces = [f + np.r_[0, [b * nt] * 4] for b, f in enumerate([tube_faces] * B)]
        faces += [f + np.r_[0, [B * nt + j * ns] * 3] for j, f in enumerate([sph_faces] * J)]
        self.mesh = pv.PolyData(np.zeros((B * nt + J * ns, 3)), np.concatenate([f.ravel() for f in faces]))
        c = _rgb(color)
        tint = {"left": c + (1 - c) * 0.35, "right": c * 0.8, "centre": c}  # left limbs lighter
        bone_rgb = np.repeat([tint[sides[j]] for _, j in self.bones], nt, 0).reshape(-1, 3)
        joint_rgb = np.repeat([c * 0.7] * J, ns, 0).reshape(-1, 3)
        self.mesh.point_data["rgb"] = (np.concatenate([bone_rgb, joint_rgb]) * 255).astype(np.uint8)
        self.mesh.point_data["Normals"] = np.zeros((self.mesh.n_points, 3))
        self.mesh.point_data.active_normals_name = "Normals"

    def update(self, pos: np.ndarray) -> None:
        """pos: (J, 3) -> rewrites the mesh's points and normals in place."""
        a, b = pos[self.bones[:, 0]], pos[self.bones[:, 1]]  # (B, 3)
        d = b - a
        L = np.linalg.norm(d, axis=-1, keepdims=True)
        e3 = np.where(L > 1e-9, d / np.maximum(L, 1e-12), [0.0, 1.0, 0.0])
        helper = np.where(np.abs(e3[:, 1:2]) < 0.9, [0.0, 1.0, 0.0], [1.0, 0.0, 0.0])
        e1 = np.cross(helper, e3)
        e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
        e2 = np.cross(e3, e1)
        t = self.tube_pts
        tube = (a[:, None] + self.rb * (t[None, :, 0:1] * e1[:, None] + t[None, :, 1:2] * e2[:, None])
                + t[None, :, 2:3] * L[:, None] * e3[:, None])  # (B, nt, 3)
        tube_n = self.tube_nrm[None, :, 0:1] * e1[:, None] + self.tube_nrm[None, :, 1:2] * e2[:, None]
        sph = pos[:, None] + self.rj * self.sph_pts[None]  # (J, ns, 3)
        sph_n = np.broadcast_to(self.sph_pts[None], sph.shape)
        self.mesh.points = np.concatenate([tube.reshape(-1, 3), sph.reshape(-1, 3)])
        self.mesh.point_data["Normals"][:] = np.concatenate([tube_n.reshape(-1, 3), sph_n.reshape(-1, 3)])
        self.mesh.Modified()


# ----------------------------------------------------------------------------- 3-D scene

@dataclass
class _Track:
    """One clip placed in the scene: positions already translated, its colour and label."""

    clip: Clip
    positions: np.ndarray  # (T, J, 3)
    color: np.ndarray
    label: str | None = None


def _view_dir(view) -> np.ndarray:
    if isinstance(view, str):
        if view not in VIEWS_3D:
            raise ValueError(f"render: view must be one of {sorted(VIEWS_3D)} or a 3-vector, got {view!r}")
        view = VIEWS_3D[view]
    v = np.asarray(view, dtype=np.float64)
    if v.shape != (3,) or np.linalg.norm(v) < 1e-9:
        raise ValueError(f"render: view vector must be a non-zero (3,), got {view!r}")
    return v / np.linalg.norm(v)


def _camera(points: np.ndarray, c: np.ndarray, size, margin: float, view_angle: float = 30.0):
    """Look-at camera from direction c that fits all points (N, 3) in an H x W image -> (position, focal)."""
    f = -c
    right = np.cross(f, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    lo, hi = points.min(0), points.max(0)
    focal = (lo + hi) / 2
    rel = points - focal  # the points themselves, not their box's corners: a row seen diagonally stays large
    u, v = rel @ right, rel @ up
    focal = focal + right * (u.max() + u.min()) / 2 + up * (v.max() + v.min()) / 2  # centred on the screen
    rel = points - focal
    ty = np.tan(np.radians(view_angle) / 2) / margin
    tx = ty * size[1] / size[0]
    depth = rel @ f  # + further from the camera
    # a corner at lateral offset s and depth z projects inside when |s| / (D + z) <= tan(half-angle)
    D = max(np.max(np.abs(rel @ up) / ty - depth), np.max(np.abs(rel @ right) / tx - depth), 0.5)
    return focal + c * D, focal


def _floor(pv, lo, hi):
    """Checkered floor mesh covering [lo, hi] in x and z (snapped to TILE), cell rgb colours."""
    x0, z0 = np.floor(lo[[0, 2]] / TILE - 3) * TILE
    x1, z1 = np.ceil(hi[[0, 2]] / TILE + 3) * TILE
    nx, nz = int(round((x1 - x0) / TILE)), int(round((z1 - z0) / TILE))
    plane = pv.Plane(center=((x0 + x1) / 2, 0.0, (z0 + z1) / 2), direction=(0, 1, 0),
                     i_size=x1 - x0, j_size=z1 - z0, i_resolution=nx, j_resolution=nz)
    cc = np.asarray(plane.cell_centers().points)
    parity = (np.floor(cc[:, 0] / TILE) + np.floor(cc[:, 2] / TILE)).astype(int) % 2
    plane.cell_data["rgb"] = np.where(parity[:, None] == 1, 218, 236).astype(np.uint8).repeat(3, 1)
    return plane


# ----------------------------------------------------------------------------- text (PIL: measured widths)

LABEL_FONT_MIN = 9  # px: smaller labels are staggered on two rows instead of shrunk further


def _font(px: int):
    from PIL import ImageFont

    return ImageFont.load_default(size=int(px))


def label_layout(centres, labels, width: int, font_px: int, pad: int = 6) -> tuple[int, list[float], list[int]]:
    """Place labels centred on pixel columns `centres` in an image `width` px wide so that none overlap.

    -> (font size, left edges, row of each label).  The font shrinks until neighbours fit on one row,
    down to LABEL_FONT_MIN; below that, a label that would have to move more than half its width goes to
    the next row down.  Edges stay inside the image.
    """
    centres = np.asarray(centres, float)
    if len(centres) != len(labels):
        raise ValueError(f"label_layout: {len(centres)} centres for {len(labels)} labels")
    order = np.argsort(centres, kind="stable")
    size = int(font_px)
    while True:
        w = np.array([_font(size).getlength(str(t)) for t in labels])
        want = np.clip(centres - w / 2, 0, np.maximum(width - w, 0))  # centred, inside the image
        pairs = zip(order[:-1], order[1:], strict=True)
        if size <= LABEL_FONT_MIN or all(want[a] + w[a] + pad <= want[b] for a, b in pairs):
            break
        size -= 1
    left, rows, ends = want.copy(), np.zeros(len(labels), int), []  # ends[r]: right edge of row r so far
    for k in order:
        for r in range(len(ends) + 1):
            if r == len(ends):
                ends.append(-np.inf)
            x = max(want[k], ends[r] + pad)
            if x - want[k] <= w[k] / 2 and x + w[k] <= width:
                break
        left[k], rows[k], ends[r] = x, r, x + w[k]
    return size, [float(v) for v in left], [int(r) for r in rows]


def label_band(width: int, centres, labels, colors=None, font_px: int = 16) -> np.ndarray:
    """A white band (h, width, 3) uint8 with the labels written over `centres` (pixel columns), never overlapping."""
    from PIL import Image, ImageDraw

    size, left, rows = label_layout(centres, labels, width, font_px)
    line = int(round(size * 1.35))
    band = Image.new("RGB", (int(width), line * (1 + max(rows, default=0)) + 4), "white")
    draw = ImageDraw.Draw(band)
    colors = colors or [(0.1, 0.1, 0.1)] * len(labels)
    for text, x, r, c in zip(labels, left, rows, colors, strict=True):
        draw.text((x, 2 + r * line), str(text), font=_font(size), fill=tuple(int(255 * v) for v in _rgb(c)))
    return np.asarray(band)


def _project_px(points: np.ndarray, position, focal, size, view_angle: float = 30.0) -> np.ndarray:
    """World points (N, 3) -> pixel columns (N,) for the look-at camera of `_camera` (image size (H, W))."""
    f = np.asarray(focal, float) - np.asarray(position, float)
    f /= np.linalg.norm(f)
    right = np.cross(f, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    rel = np.asarray(points, float) - position
    half = np.tan(np.radians(view_angle) / 2)
    ndc = (rel @ right) / (rel @ f) / (half * size[1] / size[0])
    return (ndc + 1) / 2 * size[1]



class _Scene:
    """A reusable off-screen Plotter holding characters, floor, trajectories and contact discs."""

    def __init__(self, tracks: list[_Track], frames, size, view, *, trajectory, contacts, floor,
                 bone_radius, joint_radius, follow=False, margin=1.08, lines=()):
        import pyvista as pv

        self.tracks, self.size = tracks, tuple(size)
        H, W = _check_size(size)
        c = _view_dir(view)  # validate before opening a window
        self.follow, self.frame0 = follow, frames[0]
        pts = np.concatenate([t.positions[frames].reshape(-1, 3) for t in tracks])
        floor_lo, floor_hi = pts.min(0) - joint_radius, pts.max(0) + joint_radius
        if follow:  # frame the poses as seen relative to the moving centre, placed at the first frame
            rel = np.concatenate([t.positions[frames] - self._centre(frames)[:, None] for t in tracks])
            pts = rel.reshape(-1, 3) + self._centre([frames[0]])
        pts = np.concatenate([pts, pts * [1, 0, 1]])  # keep the floor under the feet in view
        box = np.concatenate([pts + d for d in joint_radius * np.vstack([np.eye(3), -np.eye(3)])])  # joints' extent
        # labels go in a band above the 3-D picture, laid out once (they do not jump from frame to frame)
        self.band, h3d = None, H
        for _ in range(2):  # the band's height depends on the layout, the layout on the camera
            pos, focal = _camera(box, c, (h3d, W), margin)
            self.band = self._band(frames[0], pos, focal, (h3d, W), font_px=max(12, H // 16))
            if self.band is None or H - len(self.band) == h3d:
                break
            h3d = H - len(self.band)
        self.p = pv.Plotter(off_screen=True, window_size=(W, h3d), lighting="light_kit")
        self.p.set_background("white")
        self.chars = []
        for t in tracks:
            ch = _Character(t.clip.parents, _sides(t.clip), t.color, bone_radius, joint_radius)
            ch.update(t.positions[frames[0]])
            self.p.add_mesh(ch.mesh, scalars="rgb", rgb=True, interpolation="gouraud", ambient=0.25,
                            diffuse=0.8, specular=0.25)
            self.chars.append(ch)
        if floor:
            self.p.add_mesh(_floor(pv, floor_lo, floor_hi), scalars="rgb", rgb=True, lighting=False)
        if trajectory:
            for t in tracks:
                root = t.positions[:, 0] * [1, 0, 1] + [0, 0.004, 0]
                if len(root) > 1:
                    self.p.add_mesh(pv.lines_from_points(root), color=tuple(t.color * 0.7), line_width=3,
                                    lighting=False)
        for pts, color in lines:  # floor polylines (a user's curve, a path): (N, 2) (x, z) or (N, 3)
            pts = np.asarray(pts, float)
            pts = np.stack((pts[:, 0], np.zeros(len(pts)), pts[:, -1]), -1) + [0, 0.006, 0]
            self.p.add_mesh(pv.lines_from_points(pts), color=tuple(_rgb(color)), line_width=4, lighting=False)
        self.discs = self._add_discs(pv) if contacts else []
        self.p.camera.position, self.p.camera.focal_point, self.p.camera.up = pos, focal, (0.0, 1.0, 0.0)
        self.cam0 = (pos, focal)
        self.p.reset_camera_clipping_range()

    def _centre(self, frames) -> np.ndarray:
        """(F, 3) mean floor position (x, 0, z) of the tracks' roots on the given frames."""
        return np.mean([t.positions[frames, 0] for t in self.tracks], 0) * [1, 0, 1]

    def _add_discs(self, pv) -> list:
        """Per track and foot, (actor, track, foot index 0/1): discs shown under feet in contact."""
        out = []
        for t in self.tracks:
            if t.clip.contacts is None or t.clip.feet is None:
                continue
            for side in (0, 1):
                disc = pv.Disc(center=(0, 0, 0), inner=0.0, outer=0.09, normal=(0, 1, 0), c_res=24)
                actor = self.p.add_mesh(disc, color=tuple(t.color * 0.6), lighting=False, opacity=0.85)
                out.append((actor, t, side))
        return out

    def _band(self, frame: int, position, focal, size3d, font_px: int) -> np.ndarray | None:
        """(h, W, 3) band with each labelled track's label over its root on `frame`, or None without labels."""
        labelled = [t for t in self.tracks if t.label]
        if not labelled:
            return None
        xs = _project_px(np.array([t.positions[frame, 0] * [1, 0, 1] for t in labelled]), position, focal, size3d)
        return label_band(self.size[1], xs, [t.label for t in labelled], [t.color for t in labelled], font_px)

    def draw(self, frame: int) -> np.ndarray:
        """-> (H, W, 3) uint8 picture of the given frame."""
        for ch, t in zip(self.chars, self.tracks, strict=True):
            ch.update(t.positions[frame])
        for actor, t, side in self.discs:
            foot, toe = t.clip.feet[2 * side], t.clip.feet[2 * side + 1]
            actor.position = (t.positions[frame, foot] + t.positions[frame, toe]) / 2 * [1, 0, 1] + [0, 0.008, 0]
            actor.visibility = bool(t.clip.contacts[frame, side])
        if self.follow:
            shift = self._centre([frame])[0] - self._centre([self.frame0])[0]
            self.p.camera.position, self.p.camera.focal_point = self.cam0[0] + shift, self.cam0[1] + shift
            self.p.reset_camera_clipping_range()
        self.p.render()
        img = np.asarray(self.p.screenshot(return_img=True))[..., :3].copy()
        return img if self.band is None else np.concatenate([self.band, img], 0)

    def close(self) -> None:
        self.p.close()


def _check_size(size) -> tuple[int, int]:
    if len(size) != 2 or min(size) < 16:
        raise ValueError(f"render: size must be (H, W) with both >= 16 pixels, got {size}")
    return int(size[0]), int(size[1])


def _tracks(items, parents, colors, labels, center_frame: int | None, gap: float, view) -> list[_Track]:
    """Clips -> tracks translated apart along the screen's right axis (on the floor)."""
    clips = [as_clip(x, parents) for x in items]
    colors = [_rgb(c) for c in (colors or DEFAULT_COLORS[: len(clips)])]
    if len(colors) < len(clips):
        raise ValueError(f"render: {len(colors)} colours for {len(clips)} motions")
    labels = list(labels) if labels is not None else [None] * len(clips)
    if len(labels) != len(clips):
        raise ValueError(f"render: {len(labels)} labels for {len(clips)} motions")
    if len(clips) == 1:
        return [_Track(clips[0], clips[0].positions, colors[0], labels[0])]
    c = _view_dir(view)
    right = np.cross(-c, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    pos = []
    for cl in clips:
        f = _frame_index(cl, center_frame or 0)
        pos.append(cl.positions - cl.positions[f, 0] * [1, 0, 1])  # root over the origin at the centring frame
    widths = [np.ptp(p @ right) for p in pos]
    step = max(widths) + gap
    off = (np.arange(len(clips)) - (len(clips) - 1) / 2) * step
    return [_Track(cl, p + o * right, col, lab)
            for cl, p, o, col, lab in zip(clips, pos, off, colors[: len(clips)], labels, strict=True)]


_STYLE = dict(trajectory=False, contacts=True, floor=True, bone_radius=0.022, joint_radius=0.034)


def render_frame(x, parents=None, frame: int = 0, *, size=(352, 640), view="three_quarter", color=GT_COLOR,
                 **style) -> np.ndarray:
    """One pose of a Motion or of positions (J, 3) / (T, J, 3) -> (H, W, 3) uint8 image.

    view: "side" | "front" | "three_quarter" | (3,) direction towards the camera;
    style: trajectory, contacts, floor (bool), bone_radius, joint_radius (metres).
    """
    clip = as_clip(x, parents)
    f = _frame_index(clip, frame)
    scene = _Scene([_Track(clip, clip.positions, _rgb(color))], [f], size, view, **{**_STYLE, **style})
    try:
        return scene.draw(f)
    finally:
        scene.close()


def render_still(x, path=None, frame: int = 0, parents=None, *, size=(352, 640), view="three_quarter",
                 color=GT_COLOR, trajectory: bool = True, overwrite: bool = False, **style) -> np.ndarray:
    """Like `render_frame`, with the root trajectory by default; writes a PNG when path is given -> (H, W, 3)."""
    img = render_frame(x, parents, frame, size=size, view=view, color=color, trajectory=trajectory, **style)
    if path is not None:
        _write_png(img, path, overwrite)
    return img


def render_side_by_side(items, labels=None, colors=None, parents=None, frame: int = 0, path=None, *,
                        size=(360, 720), view="three_quarter", gap: float = 0.4, overwrite: bool = False,
                        **style) -> np.ndarray:
    """Several Motions / position arrays at one frame, translated apart -> (H, W, 3) uint8.

    Each is moved so its root is over the origin at `frame`, then spread along the
    screen's horizontal axis; default colours: first (ground truth) blue, second (generated) orange.
    """
    if isinstance(items, np.ndarray) or not len(items):
        raise ValueError("render_side_by_side: pass a non-empty list of Motions or position arrays")
    tracks = _tracks(items, parents, colors, labels, frame, gap, view)
    fs = [_frame_index(t.clip, frame) for t in tracks]
    if len(set(fs)) != 1:
        raise ValueError("render_side_by_side: negative frame indices resolve differently for clips of different "
                         "lengths; pass a non-negative frame")
    scene = _Scene(tracks, [fs[0]], size, view, **{**_STYLE, **style})
    try:
        img = scene.draw(fs[0])
    finally:
        scene.close()
    if path is not None:
        _write_png(img, path, overwrite)
    return img


def render_keyframes(x, frames, parents=None, *, lines=(), path=None, size=(360, 720), view="three_quarter",
                     color=GT_COLOR, trajectory: bool = True, overwrite: bool = False, **style) -> np.ndarray:
    """Several poses of one Motion / positions (T, J, 3), each where it is in the world (Fig. 8 of Wang, Chai et
    al.), the root trajectory on the floor, and ``lines``: floor polylines as ((N, 2) (x, z) or (N, 3), colour)
    pairs -> (H, W, 3) uint8; writes a PNG when path is given."""
    clip = as_clip(x, parents)
    fs = [_frame_index(clip, f) for f in frames]
    if not fs:
        raise ValueError("render_keyframes: pass at least one frame")
    tracks = [_Track(replace(clip, positions=clip.positions[f:f + 1],
                             contacts=None if clip.contacts is None else clip.contacts[f:f + 1]),
                     clip.positions[f:f + 1], _rgb(color)) for f in fs]
    lines = list(lines) + ([(clip.positions[:, 0], _rgb(color) * 0.7)] if trajectory else [])
    scene = _Scene(tracks, [0], size, view, **{**_STYLE, **style, "trajectory": False}, lines=lines)
    try:
        img = scene.draw(0)
    finally:
        scene.close()
    if path is not None:
        _write_png(img, path, overwrite)
    return img


def render_frames(x, stride: int = 1, parents=None, *, size=(352, 640), view="three_quarter", labels=None,
                  colors=None, trajectory: bool = True, gap: float = 0.4, follow: bool = True, progress: bool = False,
                  **style) -> tuple[np.ndarray, float]:
    """The frames of an animation of a Motion / positions (T, J, 3), or of a list of them side by side
    -> (images (F, H, W, 3) uint8, fps).

    One Plotter is reused; each frame only rewrites the meshes' points.  Frames 0, stride, 2*stride, ...
    are drawn at the clip's fps / stride (30 for raw positions).  With `follow=True` (default) the camera
    moves with the root(s) and frames the poses, so the character fills the picture; `follow=False` keeps
    a fixed camera that frames the whole clip.  Labels sit in a band above the picture, never overlapping.
    """
    from tqdm import tqdm

    items = list(x) if isinstance(x, (list, tuple)) else [x]
    tracks = _tracks(items, parents, colors, labels, 0, gap, view)
    if stride < 1:
        raise ValueError(f"render: stride must be >= 1, got {stride}")
    T = min(len(t.positions) for t in tracks)
    frames = list(range(0, T, stride))
    fps = tracks[0].clip.fps / stride if tracks[0].clip.fps else 30.0
    scene = _Scene(tracks, frames, size, view, **{**_STYLE, "trajectory": trajectory, **style}, follow=follow)
    try:
        images = [scene.draw(f) for f in tqdm(frames, desc="render", **({} if progress else dict(disable=True)))]
    finally:
        scene.close()
    return np.stack(images), fps


def render_gif(x, path=None, fps: float | None = None, stride: int = 1, parents=None, *, size=(240, 320),
               view="three_quarter", follow: bool = False, overwrite: bool = False, **kw) -> bytes:
    """Like `render_mp4`, as GIF bytes: only where a video player cannot be used (a GIF has no controls)."""
    _check_video_path(path, overwrite)
    images, clip_fps = render_frames(x, stride, parents, size=size, view=view, follow=follow, **kw)
    return _write_gif(images, fps or clip_fps, path, overwrite=overwrite)


def render_mp4(x, path=None, fps: float | None = None, stride: int = 1, parents=None, *, size=(352, 640),
               view="three_quarter", overwrite: bool = False, **kw) -> bytes:
    """An H.264 MP4 of a Motion / positions (T, J, 3), or of a list side by side -> bytes (`video_html` plays it).

    kw: those of `render_frames` (labels, colors, trajectory, gap, follow=True, progress, style).  Writes `path` too
    (an existing file only with overwrite=True).
    """
    _check_video_path(path, overwrite)
    images, clip_fps = render_frames(x, stride, parents, size=size, view=view, **kw)
    return write_mp4(images, fps or clip_fps, path, overwrite=overwrite)


def render_rows_mp4(rows, labels=None, colors=None, stride: int = 1, parents=None, path=None, *, size=(240, 640),
                    fps: float | None = None, overwrite: bool = False, **kw) -> bytes:
    """Rows of motions side by side, stacked into one H.264 MP4 -> bytes; `size` is one row's (H, W).

    rows: lists of Motions / positions (T, J, 3); labels, colors: lists of lists like rows (colours default to
    the same per column).  Every row is cut to the shortest clip.  kw: those of `render_frames`."""
    _check_video_path(path, overwrite)
    labels = labels or [None] * len(rows)
    colors = colors or [None] * len(rows)
    if not (len(rows) == len(labels) == len(colors)) or not len(rows):
        raise ValueError(f"render_rows_mp4: {len(rows)} rows, {len(labels)} label rows, {len(colors)} colour rows")
    videos = [render_frames(list(r), stride, parents, size=size, labels=lab, colors=col, **kw)
              for r, lab, col in zip(rows, labels, colors, strict=True)]
    n = min(len(v) for v, _ in videos)
    return write_mp4(np.concatenate([v[:n] for v, _ in videos], axis=1), fps or videos[0][1], path,
                     overwrite=overwrite)


@contextlib.contextmanager
def _ffmpeg_quietly():
    """ffmpeg runs as a subprocess (fork + exec at once: safe); JAX, once imported, warns at every fork."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=r"os\.fork\(\) was called", category=RuntimeWarning)
        yield


def _write_png(img: np.ndarray, path, overwrite: bool) -> None:
    """A picture to ``path``: a new file, or an existing one only with overwrite=True."""
    import imageio.v3 as iio

    check_outputs([path], overwrite=overwrite, who="render")
    iio.imwrite(path, img)


def _check_video_path(path, overwrite: bool) -> None:
    """A video is written to ``path`` only if it is new or overwrite=True: checked before rendering starts."""
    if path is not None:
        check_outputs([path], overwrite=overwrite, who="render")


def write_mp4(images, fps: float, path=None, quality: float = 5.0, *, overwrite: bool = False) -> bytes:
    """(F, H, W, 3) uint8 frames -> H.264 MP4 bytes (yuv420p, faststart: plays in every browser).

    Frames are padded with white to multiples of 16 pixels (the codec's macro blocks), never rescaled.  Writes
    `path` too when given (an existing file only with overwrite=True)."""
    _check_video_path(path, overwrite)
    import os
    import tempfile

    import imageio_ffmpeg

    images = np.asarray(images, dtype=np.uint8)
    if images.ndim != 4 or images.shape[-1] != 3:
        raise ValueError(f"write_mp4: frames must be (F, H, W, 3) uint8, got {images.shape}")
    F, H, W = images.shape[:3]
    ph, pw = -H % 16, -W % 16
    images = np.pad(images, ((0, 0), (0, ph), (0, pw), (0, 0)), constant_values=255)
    fd, tmp = tempfile.mkstemp(suffix=".mp4")
    os.close(fd)
    try:
        with _ffmpeg_quietly():
            writer = imageio_ffmpeg.write_frames(tmp, (W + pw, H + ph), fps=float(fps), codec="libx264",
                                                 quality=quality, macro_block_size=16,
                                                 output_params=["-movflags", "+faststart"])
            writer.send(None)  # start ffmpeg
            for img in images:
                writer.send(np.ascontiguousarray(img))
            writer.close()
        with open(tmp, "rb") as fh:
            data = fh.read()
    finally:
        os.remove(tmp)
    if path is not None:
        with open(path, "wb") as fh:
            fh.write(data)
    return data


def read_mp4(data: bytes) -> np.ndarray:
    """MP4 bytes -> (F, H, W, 3) uint8 frames (decoded by imageio-ffmpeg's ffmpeg)."""
    import os
    import tempfile

    import imageio_ffmpeg

    fd, tmp = tempfile.mkstemp(suffix=".mp4")
    with os.fdopen(fd, "wb") as fh:
        fh.write(data)
    try:
        with _ffmpeg_quietly():
            reader = imageio_ffmpeg.read_frames(tmp)
            meta = next(reader)
            W, H = meta["size"]
            frames = [np.frombuffer(f, np.uint8).reshape(H, W, 3) for f in reader]
    finally:
        os.remove(tmp)
    return np.stack(frames)


def video_html(data: bytes, width: int | None = None, loop: bool = True):
    """MP4 bytes -> an IPython HTML object: an HTML5 <video controls> (play, pause, scrub) with the video inline
    (a base64 data URI: the notebook and the course site need no extra file and no network)."""
    import base64

    from IPython.display import HTML

    size = f' width="{int(width)}"' if width else ' style="max-width: 100%"'
    src = base64.b64encode(bytes(data)).decode("ascii")
    return HTML(f'<video controls{" loop" if loop else ""} muted playsinline preload="metadata"{size}>'
                f'<source src="data:video/mp4;base64,{src}" type="video/mp4">'
                "Your browser cannot play this MP4 (H.264) video.</video>")


def _write_gif(images, fps: float, path=None, *, overwrite: bool = False) -> bytes:
    import imageio.v3 as iio

    _check_video_path(path, overwrite)
    data = iio.imwrite("<bytes>", np.stack(images), extension=".gif", duration=1000.0 / fps, loop=0)
    if path is not None:
        with open(path, "wb") as fh:
            fh.write(data)
    return data


# ----------------------------------------------------------------------------- 2-D stick figures

def project(positions: np.ndarray, view: str = "front") -> np.ndarray:
    """positions (..., 3) metres -> (..., 2) metres (image right, image up) for a 2-D view."""
    if view not in VIEWS_2D:
        raise ValueError(f"stick figure: view must be one of {sorted(VIEWS_2D)}, got {view!r}")
    right, up = (np.asarray(a) for a in VIEWS_2D[view])
    return np.stack([positions @ right, positions @ up], -1)


@dataclass
class _Frame2D:
    """Pixel mapping: world (u, v) metres -> (row, col); scale px/m, (u0, v0) at the image centre."""

    size: tuple[int, int]
    scale: float
    u0: float
    v0: float

    def to_px(self, uv: np.ndarray) -> np.ndarray:
        H, W = self.size
        return np.stack([H / 2 - (uv[..., 1] - self.v0) * self.scale, W / 2 + (uv[..., 0] - self.u0) * self.scale], -1)


def _fit(uv: np.ndarray, size, floor: bool, margin: float = 0.08) -> tuple[float, float, float]:
    """uv (N, 2) to fit -> (scale px/m, u centre, v centre)."""
    H, W = size
    lo, hi = uv.min(0), uv.max(0)
    if floor:
        lo[1], hi[1] = min(lo[1], 0.0), max(hi[1], 0.0)
    ext = np.maximum(hi - lo, 0.2)
    scale = min((W * (1 - 2 * margin)) / ext[0], (H * (1 - 2 * margin)) / ext[1])
    return scale, (lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2


def _blend(img, rr, cc, val, color) -> None:
    H, W = img.shape[:2]
    keep = (rr >= 0) & (rr < H) & (cc >= 0) & (cc < W)
    rr, cc, val = rr[keep], cc[keep], val[keep][:, None]
    img[rr, cc] = img[rr, cc] * (1 - val) + np.asarray(color) * val


def _line(img, p0, p1, color, width: float = 1.0) -> None:
    """Anti-aliased line between pixel points (row, col), `width` pixels thick (parallel line_aa strokes)."""
    from skimage.draw import line_aa

    d = np.asarray(p1, float) - np.asarray(p0, float)
    n = np.array([-d[1], d[0]]) / max(np.linalg.norm(d), 1e-9)
    for t in np.linspace(-(width - 1) / 2, (width - 1) / 2, max(int(np.ceil(width)), 1)):
        a, b = np.round(p0 + t * n).astype(int), np.round(p1 + t * n).astype(int)
        rr, cc, val = line_aa(a[0], a[1], b[0], b[1])
        _blend(img, rr, cc, val, color)


def _draw_floor(img, fr: _Frame2D, view: str) -> None:
    H, W = fr.size
    umin, umax = fr.u0 - W / 2 / fr.scale, fr.u0 + W / 2 / fr.scale
    ticks = np.arange(np.ceil(umin / TILE), np.floor(umax / TILE) + 1) * TILE
    if view == "top":  # a grid on the floor
        vmin, vmax = fr.v0 - H / 2 / fr.scale, fr.v0 + H / 2 / fr.scale
        for v in np.arange(np.ceil(vmin / TILE), np.floor(vmax / TILE) + 1) * TILE:
            _line(img, fr.to_px(np.array([umin, v])), fr.to_px(np.array([umax, v])), (0.85,) * 3)
        for u in ticks:
            _line(img, fr.to_px(np.array([u, vmin])), fr.to_px(np.array([u, vmax])), (0.85,) * 3)
        return
    _line(img, fr.to_px(np.array([umin, 0.0])), fr.to_px(np.array([umax, 0.0])), (0.6,) * 3, 2)
    for u in ticks:  # ticks every TILE metres show the character travelling when the view follows it
        _line(img, fr.to_px(np.array([u, 0.0])), fr.to_px(np.array([u, -0.06])), (0.6,) * 3, 1)


def _draw_pose(img, px: np.ndarray, parents, sides, width: float, radius: float) -> None:
    """px: (J, 2) pixel coordinates (row, col)."""
    from skimage.draw import disk

    order = sorted(_bones(parents), key=lambda b: sides[b[1]] != "centre")  # limbs over the spine
    for p, j in order:
        _line(img, px[p], px[j], STICK_COLORS[sides[j]], width)
    for j in range(len(px)):
        rr, cc = disk(tuple(px[j]), radius, shape=img.shape[:2])
        img[rr, cc] = np.asarray(STICK_COLORS[sides[j]]) * 0.7


def _render_2d(uv: np.ndarray, clip: Clip, fr: _Frame2D, view: str, floor: bool, width, radius) -> np.ndarray:
    img = np.ones((*fr.size, 3))
    if floor:
        _draw_floor(img, fr, view)
    _draw_pose(img, fr.to_px(uv), clip.parents, _sides(clip), width, radius)
    return (np.clip(img, 0, 1) * 255).round().astype(np.uint8)


def stick_figure(x, parents=None, view: str = "front", size=(200, 200), frame: int = 0, *, floor: bool = True,
                 line_width: float = 3.0, joint_radius: float = 2.5) -> np.ndarray:
    """One pose of a Motion or of positions (J, 3) / (T, J, 3) drawn as a 2-D stick figure -> (H, W, 3) uint8.

    view: "front" (looking at the character's face), "side" (from its right, +Z to
    the image's right) or "top" (from above, +Z up the image).  No OpenGL.
    """
    clip = as_clip(x, parents)
    size = _check_size(size)
    uv = project(clip.positions[_frame_index(clip, frame)], view)  # (J, 2)
    fr = _Frame2D(size, *_fit(uv, size, floor and view != "top"))
    return _render_2d(uv, clip, fr, view, floor, line_width, joint_radius)


def _follow_frames(clip: Clip, frames, view, size, floor) -> list[_Frame2D]:
    """One pixel mapping per frame: shared scale, horizontal centre following the pose."""
    uv = project(clip.positions[frames], view)  # (F, J, 2)
    local = uv - uv[:, :1] * [1, 0]  # horizontal coordinates relative to the root
    scale, _, v0 = _fit(local.reshape(-1, 2), size, floor and view != "top")
    if view == "top":  # from above, follow in both directions
        return [_Frame2D(size, scale, *u[0]) for u in uv]
    uc = (local[..., 0].min() + local[..., 0].max()) / 2
    return [_Frame2D(size, scale, u[0, 0] + uc, v0) for u in uv]


def stick_strip(x, parents=None, frames=None, view: str = "side", size=(160, 120), *, n: int = 6,
                floor: bool = True, line_width: float = 2.5, joint_radius: float = 2.0,
                labels: bool = True) -> np.ndarray:
    """A row of poses as one image -> (H + label band, n_frames * W, 3) uint8; size is one panel's (H, W).

    frames: indices to draw (default n evenly spaced).  All panels share one scale;
    each panel follows the character, floor ticks every 0.5 m show its travel.  labels: a band under
    the panels with each one's frame and, when the clip has an fps, its time ("frame 12, 0.40 s").
    """
    clip = as_clip(x, parents)
    size = _check_size(size)
    T = len(clip.positions)
    frames = np.linspace(0, T - 1, min(n, T)).round().astype(int) if frames is None else \
        np.array([_frame_index(clip, int(f)) for f in frames])
    panels = []
    for f, fr in zip(frames, _follow_frames(clip, frames, view, size, floor), strict=True):
        panel = _render_2d(project(clip.positions[f], view), clip, fr, view, floor, line_width, joint_radius)
        panel[:, -1] = 200  # thin separator
        panels.append(panel)
    strip = np.concatenate(panels, axis=1)
    if not labels:
        return strip
    texts = [f"frame {f}" + (f", {f / clip.fps:.2f} s" if clip.fps else "") for f in frames]
    centres = (np.arange(len(frames)) + 0.5) * size[1]
    return np.concatenate([strip, label_band(strip.shape[1], centres, texts, font_px=max(10, size[0] // 9))], 0)


def stick_frames(x, parents=None, view: str = "side", size=(200, 200), stride: int = 1, *, floor: bool = True,
                 line_width: float = 3.0, joint_radius: float = 2.5) -> tuple[np.ndarray, float]:
    """The frames of an animated stick figure (the view follows the character) -> ((F, H, W, 3) uint8, fps)."""
    clip = as_clip(x, parents)
    size = _check_size(size)
    if stride < 1:
        raise ValueError(f"stick animation: stride must be >= 1, got {stride}")
    frames = np.arange(0, len(clip.positions), stride)
    mappings = _follow_frames(clip, frames, view, size, floor)
    images = [_render_2d(project(clip.positions[f], view), clip, fr, view, floor, line_width, joint_radius)
              for f, fr in zip(frames, mappings, strict=True)]
    return np.stack(images), (clip.fps / stride if clip.fps else 30.0)


def stick_gif(x, path=None, parents=None, view: str = "side", size=(200, 200), fps: float | None = None,
              stride: int = 1, overwrite: bool = False, **kw) -> bytes:
    """An animated stick figure -> GIF bytes (only where no video player can be used); writes `path` when given."""
    _check_video_path(path, overwrite)
    images, clip_fps = stick_frames(x, parents, view, size, stride, **kw)
    return _write_gif(images, fps or clip_fps, path, overwrite=overwrite)


def stick_mp4(x, path=None, parents=None, view: str = "side", size=(240, 240), fps: float | None = None,
              stride: int = 1, overwrite: bool = False, **kw) -> bytes:
    """An animated stick figure -> H.264 MP4 bytes (`video_html` plays it); writes `path` when given."""
    _check_video_path(path, overwrite)
    images, clip_fps = stick_frames(x, parents, view, size, stride, **kw)
    return write_mp4(images, fps or clip_fps, path, overwrite=overwrite)


# ----------------------------------------------------------------------------- display

def show(img, title: str | None = None, ax=None, width: float = 5.0):
    """Display an (H, W, 3) image with matplotlib (returns the Axes), or GIF bytes with IPython (returns Image)."""
    if isinstance(img, (bytes, bytearray)):
        from IPython.display import Image
        return Image(data=bytes(img), format="gif")
    import matplotlib.pyplot as plt

    img = np.asarray(img)
    if ax is None:
        _, ax = plt.subplots(figsize=(width, width * img.shape[0] / img.shape[1]))
    ax.imshow(img)
    ax.set_axis_off()
    if title:
        ax.set_title(title)
    return ax


def read_gif(data: bytes) -> np.ndarray:
    """GIF bytes -> (F, H, W, 3) uint8 frames."""
    import imageio.v3 as iio

    return np.asarray(iio.imread(io.BytesIO(data), index=None, extension=".gif"))[..., :3]

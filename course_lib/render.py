"""Pictures of motion: 3-D renders with pyvista and 2-D stick figures with scikit-image.

Everything accepts either a `Motion` (uses `positions()`, `skeleton.parents`,
`skeleton.names` and `contacts()`) or raw joint positions `(J, 3)` / `(T, J, 3)`
in metres plus a `parents` array.  Conventions of the course: Y up, the
character faces +Z at rest, so its left (+X) appears on the image's right when
seen from the front.  Image sizes are always `size=(H, W)` in pixels; every
function returns `(H, W, 3)` uint8 arrays (GIFs are returned as bytes).

3-D (pyvista, needs OpenGL): `render_frame`, `render_still`, `render_gif`,
`render_side_by_side`.  Bones are tubes, joints spheres, on a checkered floor
with 0.5 m tiles; optional root trajectory and discs under feet in contact.
Headless machines must set, before Python starts (the Makefile and CI do):

    VTK_DEFAULT_OPENGL_WINDOW=vtkEGLRenderWindow PYVISTA_OFF_SCREEN=true

This module sets no environment variable and imports pyvista only inside the
3-D functions; every Plotter is created with `off_screen=True`.

2-D (scikit-image, no GL): `stick_figure`, `stick_strip`, `stick_gif` draw
anti-aliased lines (`skimage.draw.line_aa`) and joint disks; left limbs blue,
right limbs red, the spine grey.  `show(img)` displays an image with matplotlib
(or a GIF's bytes with IPython), never with pyvista's notebook widgets.

Taught in notebooks/00_skeletons_and_rotations.ipynb; used by every lesson.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

import numpy as np

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
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    focal = (lo + hi) / 2
    rel = corners - focal
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


class _Scene:
    """A reusable off-screen Plotter holding characters, floor, trajectories and contact discs."""

    def __init__(self, tracks: list[_Track], frames, size, view, *, trajectory, contacts, floor,
                 bone_radius, joint_radius, follow=False, margin=1.08):
        import pyvista as pv

        self.tracks, self.size = tracks, tuple(size)
        H, W = _check_size(size)
        c = _view_dir(view)  # validate before opening a window
        self.p = pv.Plotter(off_screen=True, window_size=(W, H), lighting="light_kit")
        self.p.set_background("white")
        self.chars = []
        for t in tracks:
            ch = _Character(t.clip.parents, _sides(t.clip), t.color, bone_radius, joint_radius)
            ch.update(t.positions[frames[0]])
            self.p.add_mesh(ch.mesh, scalars="rgb", rgb=True, interpolation="gouraud", ambient=0.25,
                            diffuse=0.8, specular=0.25)
            self.chars.append(ch)
        pts = np.concatenate([t.positions[frames].reshape(-1, 3) for t in tracks])
        pts = np.concatenate([pts, pts * [1, 0, 1]])  # keep the floor under the feet in view
        lo, hi = pts.min(0) - joint_radius, pts.max(0) + joint_radius
        if floor:
            self.p.add_mesh(_floor(pv, lo, hi), scalars="rgb", rgb=True, lighting=False)
        self.follow, self.frame0 = follow, frames[0]
        if follow:  # frame the poses as seen relative to the moving centre, placed at the first frame
            rel = np.concatenate([t.positions[frames] - self._centre(frames)[:, None] for t in tracks])
            pts = rel.reshape(-1, 3) + self._centre([frames[0]])
            pts = np.concatenate([pts, pts * [1, 0, 1]])
            lo, hi = pts.min(0) - joint_radius, pts.max(0) + joint_radius
        if trajectory:
            for t in tracks:
                root = t.positions[:, 0] * [1, 0, 1] + [0, 0.004, 0]
                if len(root) > 1:
                    self.p.add_mesh(pv.lines_from_points(root), color=tuple(t.color * 0.7), line_width=3,
                                    lighting=False)
        self.discs = self._add_discs(pv) if contacts else []
        anchors = self._labels(pts, frames[0])
        pos, focal = _camera(np.concatenate([[lo, hi], anchors]), c, (H, W), margin)
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

    def _labels(self, pts, frame: int) -> np.ndarray:
        """Text above each labelled track (at its root on `frame`) -> (n, 3) anchor points for framing."""
        top = pts[:, 1].max() + 0.2
        anchors = []
        if self.follow:  # screen-space text, spread like the tracks (which are spread left to right)
            n = len(self.tracks)
            for k, t in enumerate(self.tracks):
                if t.label:
                    self.p.add_text(t.label, position=((k + 0.5) / n - 0.04 * len(t.label) / n, 0.92),
                                    viewport=True, font_size=max(7, self.size[0] // 30), color=tuple(t.color))
            return np.zeros((0, 3))
        for t in self.tracks:
            if t.label:
                x = t.positions[frame, 0] * [1, 0, 1] + [0, top, 0]
                self.p.add_point_labels([x], [t.label], font_size=max(10, self.size[0] // 18), text_color="black",
                                        shape_opacity=0.0, show_points=False, always_visible=True, bold=True,
                                        justification_horizontal="center")
                anchors.append(x + [0, 0.15, 0])
        return np.reshape(anchors, (-1, 3))

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
        return np.asarray(self.p.screenshot(return_img=True))[..., :3].copy()

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


def render_frame(x, parents=None, frame: int = 0, *, size=(360, 360), view="three_quarter", color=GT_COLOR,
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


def render_still(x, path=None, frame: int = 0, parents=None, *, size=(360, 360), view="three_quarter",
                 color=GT_COLOR, trajectory: bool = True, **style) -> np.ndarray:
    """Like `render_frame`, with the root trajectory by default; writes a PNG when path is given -> (H, W, 3)."""
    img = render_frame(x, parents, frame, size=size, view=view, color=color, trajectory=trajectory, **style)
    if path is not None:
        import imageio.v3 as iio
        iio.imwrite(path, img)
    return img


def render_side_by_side(items, labels=None, colors=None, parents=None, frame: int = 0, path=None, *,
                        size=(360, 540), view="three_quarter", gap: float = 0.4, **style) -> np.ndarray:
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
        import imageio.v3 as iio
        iio.imwrite(path, img)
    return img


def render_gif(x, path=None, fps: float | None = None, stride: int = 1, parents=None, *, size=(240, 320),
               view="three_quarter", labels=None, colors=None, trajectory: bool = True, gap: float = 0.4,
               follow: bool = False, progress: bool = False, **style) -> bytes:
    """An animation of a Motion / positions (T, J, 3), or of a list of them side by side -> GIF bytes.

    One Plotter is reused; each frame only rewrites the meshes' points.  Frames
    0, stride, 2*stride, ... are drawn; fps defaults to the clip's fps / stride
    (30 for raw positions).  The camera is fixed and frames the whole clip, or, with
    `follow=True`, moves with the root(s) and frames the poses (closer for long clips).
    Writes the GIF to `path` too when given.
    """
    from tqdm import tqdm

    items = list(x) if isinstance(x, (list, tuple)) else [x]
    tracks = _tracks(items, parents, colors, labels, 0, gap, view)
    if stride < 1:
        raise ValueError(f"render_gif: stride must be >= 1, got {stride}")
    T = min(len(t.positions) for t in tracks)
    frames = list(range(0, T, stride))
    fps = fps or (tracks[0].clip.fps / stride if tracks[0].clip.fps else 30.0)
    scene = _Scene(tracks, frames, size, view, **{**_STYLE, "trajectory": trajectory, **style}, follow=follow)
    try:
        images = [scene.draw(f) for f in tqdm(frames, desc="render_gif", **({} if progress else dict(disable=True)))]
    finally:
        scene.close()
    return _write_gif(images, fps, path)


def _write_gif(images, fps: float, path=None) -> bytes:
    import imageio.v3 as iio

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
                floor: bool = True, line_width: float = 2.5, joint_radius: float = 2.0) -> np.ndarray:
    """A row of poses as one image -> (H, n_frames * W, 3) uint8; size is one panel's (H, W).

    frames: indices to draw (default n evenly spaced).  All panels share one scale;
    each panel follows the character, floor ticks every 0.5 m show its travel.
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
    return np.concatenate(panels, axis=1)


def stick_gif(x, path=None, parents=None, view: str = "side", size=(200, 200), fps: float | None = None,
              stride: int = 1, *, floor: bool = True, line_width: float = 3.0, joint_radius: float = 2.5) -> bytes:
    """An animated stick figure (the view follows the character) -> GIF bytes; writes `path` when given."""
    clip = as_clip(x, parents)
    size = _check_size(size)
    if stride < 1:
        raise ValueError(f"stick_gif: stride must be >= 1, got {stride}")
    frames = np.arange(0, len(clip.positions), stride)
    mappings = _follow_frames(clip, frames, view, size, floor)
    images = [_render_2d(project(clip.positions[f], view), clip, fr, view, floor, line_width, joint_radius)
              for f, fr in zip(frames, mappings, strict=True)]
    return _write_gif(images, fps or (clip.fps / stride if clip.fps else 30.0), path)


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

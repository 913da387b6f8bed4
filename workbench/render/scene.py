"""Skeleton scenes: panes side by side with one shared camera (noisy | cleaned | truth,
or one pane per engine), a floor grid, joints coloured by their current error on a
colour scale (drawn beside the scene, by :func:`workbench.plots.style.error_mappable`),
the ground truth faded into the cleaned panes, missing joints grey.

Units: positions in the take's file unit (``unit_cm`` cm each), Y up (a take standing on
another axis is shown turned upright, :func:`skeleton_points`); errors in cm;
pixel coordinates have their origin at the window's top left, x to the right, in
render-window pixels.

Frames update in place: each pane owns PolyData whose points (and the joints'
``error_cm`` scalars) are replaced per frame, so playing never re-adds actors. Joints
are drawn unlit, so a joint's pixels are exactly its colour-map colour. Anti-aliasing is
off: 8x multisampling triples the cost of a frame in software rendering.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.upright import turn_vectors, up_turn
from ..plots.style import JOINTS, MISSING, PLAIN, TEXT, TRUTH, error_cmap

BACKGROUND = "#f3f5f8"  # flat: a gradient costs half again per frame in software
FLOOR, GRID = "#e9ecf0", "#b9c0ca"
BONE = "#3a4350"
PLOTTER_OPTIONS = dict(border=True, border_color="#c5cbd3", border_width=1.0)
JOINT_PX, BONE_PX, GHOST_PX, HALO_PX = 11, 3, 5, 23
LOOK_AT = 0.56  # the camera looks at this height (times body height) above the floor
HALO_BEHIND = 0.04  # a selected joint's halo sits this far (times body height) behind it
#: metres from its path's median past which the body root is a stray frame (an exporter's
#: glitch put one public take's body 1.5 km off), left out of the floor and the framing
STRAY_M = 100.0
#: metres from the body root past which a point is not the body's (an engine thrown by such
#: frames), left out of the framing too
REACH_M = 3.0
GHOST_OPACITY = 0.35


def _faded(colour: str, share: float, under: str) -> tuple[float, float, float]:
    """``colour`` at ``share`` over ``under``, as an opaque RGB colour."""
    from matplotlib.colors import to_rgb

    return tuple(share * a + (1 - share) * b for a, b in zip(to_rgb(colour), to_rgb(under)))


#: the truth faded in, drawn opaque in the colour it would have at GHOST_OPACITY over the
#: background: a translucent actor costs VTK a translucent pass, a quarter of each frame's
#: render on the software renderer
GHOST = _faded(TRUTH, GHOST_OPACITY, BACKGROUND)
#: depth-buffer units the skeleton's bones are drawn nearer by, in front of the ghost near them
SKELETON_DEPTH_OFFSET = 3000.0
PICK_RADIUS_PX = 14


def skeleton_points(motion) -> np.ndarray:
    """(F, J + E, 3) joint positions then End Site positions, in file units, turned
    upright (Y up) where the take stands on another axis
    (:func:`workbench.core.upright.up_turn`)."""
    points = np.concatenate([motion.positions, motion.end_site_positions()], axis=1)
    turn = up_turn(motion)
    return points if turn is None else turn_vectors(points, turn)


def bone_lines(skeleton) -> np.ndarray:
    """VTK line cells joining every joint and End Site to its parent, indexing
    :func:`skeleton_points`; none within the root chain (a studio export's Hips, carried
    by its reference node at the origin, hangs from no bone)."""
    J = skeleton.n_joints
    pairs = [(p, j) for j, p in enumerate(skeleton.parents) if p >= 0 and j not in skeleton.root_chain]
    pairs += [(p, J + e) for e, (p, _) in enumerate(skeleton.end_sites)]
    return np.array([(2, a, b) for a, b in pairs], dtype=np.int64).ravel()


@dataclass(frozen=True)
class Pane:
    """One 3D view. points: (F, J + E, 3) skeleton or None (then ``note`` is shown);
    errors_cm: (F, J) colouring the joints, or None for one plain ``colour``; missing:
    (F, J) bool, drawn grey; ghost: (F, J + E, 3) skeleton faded in (the truth)."""

    title: str
    points: np.ndarray | None = None
    errors_cm: np.ndarray | None = None
    missing: np.ndarray | None = None
    ghost: np.ndarray | None = None
    colour: str = PLAIN
    note: str = ""


def new_plotter(n_panes: int, size: tuple[int, int]):
    """An off-screen plotter with ``n_panes`` side by side, ``size`` (width, height) px."""
    import pyvista as pv

    return pv.Plotter(
        off_screen=True, shape=(1, n_panes), window_size=list(size), theme=plain_theme(), **PLOTTER_OPTIONS
    )


def plain_theme():
    """pyvista theme for these scenes: no multisampling, dark text."""
    import pyvista as pv

    theme = pv.themes.DocumentTheme()
    theme.anti_aliasing = None
    theme.multi_samples = 0
    theme.font.color = TEXT
    theme.show_scalar_bar = False
    return theme


class _PaneActors:
    """The PolyData of one pane, updated per frame."""

    def __init__(self, plotter, pane: Pane, lines: np.ndarray, n_joints: int, clim, cmap) -> None:
        import pyvista as pv
        from matplotlib.colors import ListedColormap

        self.pane, self.J = pane, n_joints
        self.bones = self.joints = self.ghost = None
        if pane.ghost is not None:
            self.ghost = pv.PolyData(pane.ghost[0], lines=lines)
            plotter.add_mesh(self.ghost, color=GHOST, line_width=GHOST_PX, lighting=False, pickable=False)
        if pane.points is None:
            return
        self.bones = pv.PolyData(pane.points[0], lines=lines)
        actor = plotter.add_mesh(self.bones, color=BONE, line_width=BONE_PX, lighting=False, pickable=False)
        # in front of the opaque ghost where they meet, as through a translucent one
        actor.mapper.SetResolveCoincidentTopologyToPolygonOffset()
        actor.mapper.SetRelativeCoincidentTopologyLineOffsetParameters(0.0, -SKELETON_DEPTH_OFFSET)
        self.joints = pv.PolyData(pane.points[0, :n_joints])
        self.joints.point_data["error_cm"] = self._scalars(0)
        joints = plotter.add_mesh(
            self.joints,
            scalars="error_cm",
            clim=clim,
            nan_color=MISSING,
            point_size=JOINT_PX,
            render_points_as_spheres=True,
            lighting=False,
            pickable=False,
            show_scalar_bar=False,
            cmap=cmap if pane.errors_cm is not None else ListedColormap([pane.colour]),
        )
        joints.mapper.SetResolveCoincidentTopologyToPolygonOffset()  # and the joints in front of the bones
        joints.mapper.SetRelativeCoincidentTopologyPointOffsetParameter(-2 * SKELETON_DEPTH_OFFSET)

    def _scalars(self, f: int) -> np.ndarray:
        p = self.pane
        values = np.zeros(self.J) if p.errors_cm is None else np.array(p.errors_cm[f], dtype=float)
        if p.missing is not None:
            values[p.missing[f]] = np.nan
        return values

    def set_frame(self, f: int) -> None:
        if self.ghost is not None:
            self.ghost.points = self.pane.ghost[f]
        if self.bones is not None:
            self.bones.points = self.pane.points[f]
            self.joints.points = self.pane.points[f, : self.J]
            self.joints.point_data["error_cm"] = self._scalars(f)


class SkeletonScene:
    """Builds panes into a plotter whose shape is (1, len(panes)) and moves them through
    time. ``root``: (F, 3) the trajectory the camera follows; ``clim_cm``: the error
    colour scale (lo, hi) in cm; ``keep_camera``: do not re-aim a camera already set up
    (a rebuild while the user has turned the view); ``selected``: joints ringed in the
    plots' joint colours."""

    def __init__(
        self,
        plotter,
        panes: list[Pane],
        skeleton,
        root: np.ndarray,
        clim_cm: tuple[float, float],
        follow: bool = True,
        keep_camera: bool = False,
        selected: tuple[int, ...] = (),
    ) -> None:
        self.plotter, self.panes, self.root, self.follow = plotter, panes, np.asarray(root, float), follow
        self.J = skeleton.n_joints
        self.unit_cm = skeleton.unit_cm
        lines = bone_lines(skeleton)
        metre = 100.0 / self.unit_cm
        self.framed = ~(np.linalg.norm(self.root - np.nanmedian(self.root, axis=0), axis=1) > STRAY_M * metre)
        root = self.root[self.framed, None]  # the floor and camera fit these frames, and in them the body's points
        stacks = [a[self.framed] for p in panes for a in (p.points, p.ghost) if a is not None]
        near = [s[..., 1][~(np.linalg.norm(s - root, axis=-1) > REACH_M * metre)] for s in stacks]
        ys = np.concatenate(near or [np.zeros(1)])
        self.floor_y = float(np.nanmin(ys))
        self.height = max(float(np.nanmax(ys)) - self.floor_y, 1e-6)
        self.frame = 0
        self.halos: list[tuple[int, object, object]] = []  # (pane, PolyData, actor)
        suppressed, plotter.suppress_rendering = plotter.suppress_rendering, True  # one render, by the caller
        try:
            self._build(lines, clim_cm)
            self.set_selection(selected)
            if not keep_camera:
                self.aim_camera()
            self.set_frame(0)
        finally:
            plotter.suppress_rendering = suppressed

    def _build(self, lines: np.ndarray, clim_cm: tuple[float, float]) -> None:
        plotter = self.plotter
        plotter.clear_actors()
        self.actors = []
        cmap = error_cmap()
        for i, pane in enumerate(self.panes):
            plotter.subplot(0, i)
            plotter.set_background(BACKGROUND)
            self._add_floor()
            actors = _PaneActors(plotter, pane, lines, self.J, clim_cm, cmap)
            self.actors.append(actors)
            self._add_text(pane.title, (0.03, 0.97), "left")
            if pane.note:
                self._add_text(pane.note, (0.5, 0.6), "center")
        if len(self.panes) > 1:
            plotter.link_views()

    def set_selection(self, joints: tuple[int, ...]) -> None:
        """Ring ``joints`` in every pane with a skeleton (the k-th in ``JOINTS[k]``)."""
        import pyvista as pv
        from matplotlib.colors import ListedColormap

        for _, _, actor in self.halos:
            self.plotter.remove_actor(actor, render=False)
        self.selected, self.halos = tuple(joints), []
        if not self.selected:
            return
        colours = [JOINTS[k % len(JOINTS)] for k in range(len(self.selected))]
        for i, pane in enumerate(self.panes):
            if pane.points is None:
                continue
            self.plotter.subplot(0, i)
            poly = pv.PolyData(pane.points[self.frame, list(self.selected)])
            poly.point_data["k"] = np.arange(len(self.selected), dtype=float)
            actor = self.plotter.add_mesh(
                poly,
                scalars="k",
                cmap=ListedColormap(colours),
                clim=(-0.5, len(colours) - 0.5),
                point_size=HALO_PX,
                render_points_as_spheres=True,
                lighting=False,
                pickable=False,
                show_scalar_bar=False,
            )
            self.halos.append((i, poly, actor))
        self._place_halos()

    def _place_halos(self) -> None:
        """Halos just behind their joints, seen from the camera, so the joints stay on top."""
        eye = np.array(self.plotter.renderers[0].camera.position)
        for i, poly, _ in self.halos:
            p = self.panes[i].points[self.frame, list(self.selected)]
            away = p - eye
            poly.points = p + HALO_BEHIND * self.height * away / np.linalg.norm(away, axis=1, keepdims=True)

    def _add_text(self, text: str, xy: tuple[float, float], justify: str) -> None:
        """Text at a fixed size, anchored at its top, ``xy`` in viewport fractions."""
        actor = self.plotter.add_text(text, position=xy, viewport=True, font_size=7, color=TEXT)
        actor.prop.justification_horizontal = justify
        actor.prop.justification_vertical = "top"

    # -- geometry -------------------------------------------------------------------
    def _add_floor(self) -> None:
        import pyvista as pv

        cell = 100.0 / self.unit_cm  # one metre
        xz = self.root[self.framed][:, [0, 2]]
        lo = np.nanmin(xz, axis=0) - 1.2 * self.height
        hi = np.nanmax(xz, axis=0) + 1.2 * self.height
        lo, hi = np.floor(lo / cell) * cell, np.ceil(hi / cell) * cell
        n = np.maximum(np.round((hi - lo) / cell).astype(int), 1)
        centre = ((lo[0] + hi[0]) / 2, self.floor_y, (lo[1] + hi[1]) / 2)
        grid = pv.Plane(
            center=centre,
            direction=(0, 1, 0),
            i_size=hi[1] - lo[1],
            j_size=hi[0] - lo[0],
            i_resolution=int(n[1]),
            j_resolution=int(n[0]),
        )
        self.plotter.add_mesh(grid, color=FLOOR, lighting=False, pickable=False)
        self.plotter.add_mesh(
            grid.translate((0, 0.002 * self.height, 0)),
            style="wireframe",
            color=GRID,
            line_width=1,
            lighting=False,
            pickable=False,
        )

    def aim_camera(self) -> None:
        """A three-quarter side view of the walking direction, the whole body in view;
        when not following, the whole trajectory (but stray frames)."""
        xz = self.root[self.framed][:, [0, 2]]
        travel = xz[-1] - xz[0]
        fwd = travel / np.linalg.norm(travel) if np.linalg.norm(travel) > 0.5 * self.height else np.array([0.0, 1.0])
        side = np.array([fwd[1], -fwd[0]])
        a = np.radians(30.0)
        d = side * np.cos(a) + fwd * np.sin(a)
        view = np.array([d[0], np.tan(np.radians(12.0)), d[1]])
        view /= np.linalg.norm(view)
        x0, y0, x1, y1 = self.plotter.renderers[0].GetViewport()
        W, H = self.plotter.window_size
        aspect = max((x1 - x0) * W, 1.0) / max((y1 - y0) * H, 1.0)
        span = 1.4 * self.height * max(1.0, 0.6 / aspect)  # the height to see, titles above
        if self.follow:
            focal = self._anchor(self.frame)
        else:
            focal = np.array([xz[:, 0].mean(), self.floor_y + LOOK_AT * self.height, xz[:, 1].mean()])
            span += float(np.ptp(xz, axis=0).max())
        dist = span / (2 * np.tan(np.radians(15.0)))
        cam = self.plotter.renderers[0].camera
        cam.focal_point = tuple(focal)
        cam.position = tuple(focal + dist * view)
        cam.up = (0.0, 1.0, 0.0)
        cam.view_angle = 30.0
        for ren in self.plotter.renderers:
            ren.ResetCameraClippingRange()

    def _anchor(self, f: int) -> np.ndarray:
        x, _, z = self.root[f]
        return np.array([x, self.floor_y + LOOK_AT * self.height, z])

    # -- time -----------------------------------------------------------------------
    def set_frame(self, f: int) -> None:
        """Show frame ``f`` in every pane (the caller renders)."""
        self.frame = int(f)
        for actors in self.actors:
            actors.set_frame(self.frame)
        if self.follow:  # move the camera with the root, keeping the user's view angle and zoom
            cam = self.plotter.renderers[0].camera
            anchor = self._anchor(self.frame)
            cam.position = tuple(np.array(cam.position) + anchor - np.array(cam.focal_point))
            cam.focal_point = tuple(anchor)
        self._place_halos()

    def set_follow(self, follow: bool) -> None:
        self.follow = bool(follow)
        self.aim_camera()

    # -- pixels ---------------------------------------------------------------------
    def project(self, pane: int, xyz: np.ndarray) -> np.ndarray:
        """(N, 2) pixel (x, y) of world points (N, 3) in pane ``pane``."""
        ren = self.plotter.renderers[pane]
        W, H = self.plotter.window_size
        x0, y0, x1, y1 = ren.GetViewport()
        pw, ph = (x1 - x0) * W, (y1 - y0) * H
        m = ren.camera.GetCompositeProjectionTransformMatrix(pw / ph, -1, 1)
        M = np.array([[m.GetElement(i, j) for j in range(4)] for i in range(4)])
        h = np.c_[np.asarray(xyz, float), np.ones(len(xyz))] @ M.T
        ndc = h[:, :2] / h[:, 3:]
        px = x0 * W + (ndc[:, 0] + 1) / 2 * pw
        py = H - (y0 * H + (ndc[:, 1] + 1) / 2 * ph)
        return np.c_[px, py]

    def pane_at(self, x: float, y: float) -> int | None:
        W, H = self.plotter.window_size
        for i, ren in enumerate(self.plotter.renderers[: len(self.panes)]):
            x0, y0, x1, y1 = ren.GetViewport()
            if x0 * W <= x < x1 * W and (1 - y1) * H <= y < (1 - y0) * H:
                return i
        return None

    def pick(self, x: float, y: float) -> int | None:
        """The joint drawn nearest pixel (x, y), within a few pixels, in the current frame."""
        pane = self.pane_at(x, y)
        if pane is None or self.panes[pane].points is None:
            return None
        px = self.project(pane, self.panes[pane].points[self.frame, : self.J])
        d = np.hypot(px[:, 0] - x, px[:, 1] - y)
        j = int(np.argmin(d))
        return j if d[j] <= PICK_RADIUS_PX else None

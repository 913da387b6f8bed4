"""pyvista scene builders for skeletons, with no Qt: the app's 3D views, the report's
images and the screenshot tests all draw through :class:`SkeletonScene`."""

from .scene import Pane, SkeletonScene, new_plotter, skeleton_points

__all__ = ["Pane", "SkeletonScene", "new_plotter", "skeleton_points"]

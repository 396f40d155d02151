"""Pose tracks keyed into a meshcat animation and written as a standalone HTML replay.

:func:`write_replay_html` is the one writer of replay files: it turns per-frame transforms
into position/quaternion(/scale) tracks, sends them as one animation and writes the page of
the visualizer (served, or offline from :mod:`pbvs_pin.viz.recorder`).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from pbvs_pin.viz.primitives import _as_homogeneous

if TYPE_CHECKING:  # pragma: no cover - typing only
    import meshcat

__all__ = ["write_replay_html"]

PoseSource = Mapping[str, np.ndarray] | Callable[[int, float], Mapping[str, np.ndarray]]


def _decompose(T: np.ndarray) -> tuple[list[float], np.ndarray, list[float]]:
    """Split a 4x4 transform into position, xyzw quaternion and column scale."""
    scale = np.linalg.norm(T[:3, :3], axis=0)
    if np.any(scale <= 0):
        raise ValueError("degenerate transform (zero scale)")
    R = T[:3, :3] / scale[None, :]
    if np.linalg.det(R) < 0:
        raise ValueError("mirroring transforms cannot be animated")
    quat = pin.Quaternion(R).normalized().coeffs()  # x, y, z, w
    return list(map(float, T[:3, 3])), np.array(quat, dtype=float), list(map(float, scale))


def _collect_poses(times: np.ndarray, poses: PoseSource) -> dict[str, np.ndarray]:
    """Normalise ``poses`` to ``{path: (T, 4, 4)}``."""
    n = len(times)
    if callable(poses):
        per_frame = [poses(k, float(t)) for k, t in enumerate(times)]
        keys = list(per_frame[0].keys())
        for k, frame in enumerate(per_frame):
            if set(frame.keys()) != set(keys):
                raise ValueError(f"frame {k} animates different paths than frame 0")
        return {p: np.stack([_as_homogeneous(f[p]) for f in per_frame]) for p in keys}
    out: dict[str, np.ndarray] = {}
    for p, arr in poses.items():
        arr = np.asarray(arr, dtype=float)
        if arr.shape != (n, 4, 4):
            raise ValueError(f"poses[{p!r}] must have shape ({n}, 4, 4), got {arr.shape}")
        out[p] = arr
    return out


def write_replay_html(
    path: str | Path,
    vis: meshcat.Visualizer,
    times: np.ndarray,
    poses: PoseSource,
    fps: float = 30.0,
    play: bool = True,
    repetitions: int = 1,
) -> Path:
    """Animate objects and write a standalone HTML replay.

    For every frame ``k`` and every animated path, the object's position and
    quaternion (and scale, if not 1) are keyed at time ``times[k]`` in a
    ``meshcat.animation.Animation``; frame 0 is also set as the static
    transform.  The animation is sent with ``vis.set_animation(anim,
    play=play)`` and ``vis.static_html()`` (which needs the meshcat server
    that ``vis`` talks to) is written to ``path``.  The file embeds the viewer
    JavaScript, all meshes and the animation, so it opens from ``file://``
    without any server.  In the page, ``viewer.animator.seek(t)`` jumps to
    time ``t`` (seconds); three.js interpolates linearly (slerp for
    rotations) between keys.

    Args:
        path: Output HTML file.
        vis: Visualizer holding the scene (objects must already be added).
        times: Key times, shape (T,), seconds, non-negative, increasing.
        poses: Either ``{path: array (T, 4, 4)}`` or a callable
            ``poses(k, t) -> {path: 4x4 or pin.SE3}`` called for every frame
            (all frames must return the same paths).  Paths are relative to
            ``vis`` (e.g. ``"pbvs/robot/base_link_0"``); a node's transform is
            relative to its parent node.
        fps: Nominal frame rate of the clip; only changes the key numbering
            (frame = t * fps), not the timing.
        play: Start playing on load.  Must be True for the page's
            ``viewer.animator.seek`` to work: the three.js actions exist
            either way, but only ``action.play()`` activates them in the
            mixer, and seeking an inactive action moves nothing.
        repetitions: Number of plays before stopping.

    Returns:
        The path of the written file.
    """
    from meshcat.animation import Animation

    times = np.asarray(times, dtype=float).reshape(-1)
    if times.size == 0:
        raise ValueError("times is empty")
    if np.any(times < 0) or np.any(np.diff(times) <= 0):
        raise ValueError("times must be non-negative and strictly increasing")
    tracks = _collect_poses(times, poses)

    anim = Animation(default_framerate=fps)
    for obj_path, arr in tracks.items():
        decomposed = [_decompose(T) for T in arr]
        has_scale = any(np.max(np.abs(np.array(s) - 1.0)) > 1e-9 for _, _, s in decomposed)
        prev_q = None
        node = anim.at_frame(vis, 0)[obj_path]
        for t, (pos, quat, scale) in zip(times, decomposed, strict=True):
            if prev_q is not None and float(np.dot(prev_q, quat)) < 0.0:
                quat = -quat  # keep the quaternion track continuous
            prev_q = quat
            node.current_frame = float(t) * fps
            node.set_property("position", "vector3", pos)
            node.set_property("quaternion", "quaternion", list(map(float, quat)))
            if has_scale:
                node.set_property("scale", "vector3", scale)
        vis[obj_path].set_transform(arr[0])

    vis.set_animation(anim, play=play, repetitions=repetitions)
    html = vis.static_html()
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(html, encoding="utf-8")
    return out

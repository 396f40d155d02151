"""The scene drawn by MuJoCo from the camera, at the camera's intrinsics and image size.

:class:`SceneRenderer` builds a MuJoCo model of the *scene* (not of the physics) from the
robot's assembled URDF (:attr:`pbvs_pin.model.robot.MobileManipulator.urdf_xml`, through MuJoCo's
URDF importer with its visual geometry kept, colours from the URDF's materials), adds the two
target spheres (mocap bodies, colours of :data:`pbvs_pin.perception.detection.SPHERE_HUES`), the
obstacles (vertical prisms of their height), a checkered floor, an overhead light and the
camera's headlight. :meth:`SceneRenderer.render` places the robot at a configuration of the
controller's model (planar pose and arm joints, as :class:`pbvs_pin.plant.mujoco_plant.MujocoPlant`
does), the spheres at their centres and MuJoCo's camera at ``world_T_camera``, and draws with
MuJoCo's offscreen renderer. It draws only the pose it is given: on either plant engine the
scene's own model has no physics.

The camera: MuJoCo's camera looks along its ``-z`` with ``y`` up, the optical frame (REP-103)
along ``z`` with ``y`` down, so ``R_mujoco = R_optical diag(1, -1, -1)``; the vertical field
of view is ``2 atan(H / (2 f))`` with square pixels and the principal point at the image
centre, as :class:`pbvs_pin.model.camera.CameraIntrinsics` has.

Headless rendering needs an OpenGL context without a display: ``MUJOCO_GL=egl`` (Debian's
``libegl1`` and ``libegl-mesa0``, Mesa's software rasteriser when there is no GPU) or
``MUJOCO_GL=osmesa`` (``libosmesa6``). MuJoCo reads the variable when it is first imported;
this module sets it to ``egl`` when it is not set and MuJoCo is not imported yet.
"""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path

if "mujoco" not in sys.modules:
    os.environ.setdefault("MUJOCO_GL", "egl")

import mujoco
import numpy as np
import pinocchio as pin
from lxml import etree

from pbvs_pin.exceptions import PbvsWarning, RenderingUnavailable, UrdfError
from pbvs_pin.model import frames
from pbvs_pin.model.camera import CameraIntrinsics
from pbvs_pin.model.robot import MobileManipulator
from pbvs_pin.perception.detection import SPHERE_HUES, sphere_rgba
from pbvs_pin.sim.obstacles import BoxObstacle, CircleObstacle, Obstacle

OPTICAL_TO_MUJOCO = np.diag([1.0, -1.0, -1.0])
"""Rotation from MuJoCo's camera axes (x right, y up, looking along -z) to the optical frame."""

OBSTACLE_RGBA = (0.55, 0.5, 0.45, 1.0)
"""Colour of the obstacles (a grey-brown of low saturation)."""

FLOOR_RGB = ((0.45, 0.45, 0.45), (0.6, 0.6, 0.6))
"""The floor's two checker greys."""

NEAR_CLIP = 0.01
"""Distance [m] from the camera of the near clipping plane."""


MESH_FORMATS = (".stl", ".obj", ".msh")
"""Mesh files MuJoCo decodes without a plugin (a URDF's ``.glb``, ``.gltf`` or ``.dae`` not)."""


def _drawable(geom: mujoco.MjsGeom, files: dict[str, str]) -> bool:
    """Whether MuJoCo can draw ``geom`` (a primitive, or a mesh in :data:`MESH_FORMATS`)."""
    if geom.type != mujoco.mjtGeom.mjGEOM_MESH:
        return True
    return files.get(geom.meshname, "").lower().endswith(MESH_FORMATS)


def _formats(files: dict[str, str]) -> str:
    """The file formats of meshes MuJoCo cannot decode, e.g. ``.glb``."""
    found = {Path(file).suffix.lower() for file in files.values()}
    return ", ".join(sorted(found - set(MESH_FORMATS)))


def _visual_urdf(robot: MobileManipulator) -> str:
    """The robot's URDF with MuJoCo's ``discardvisual`` off (visual geometry kept)."""
    if robot.urdf_xml is None:
        raise UrdfError(robot.source, "rendered camera: expected a robot built from a URDF")
    xml = robot.urdf_xml
    root = etree.fromstring(xml.encode() if isinstance(xml, str) else xml)
    extension = etree.SubElement(root, "mujoco")
    etree.SubElement(extension, "compiler", discardvisual="false", fusestatic="false")
    return etree.tostring(root).decode()


def scene_spec(
    robot: MobileManipulator,
    camera: CameraIntrinsics,
    diameter: float,
    obstacles: list[Obstacle],
) -> mujoco.MjSpec:
    """The scene's MuJoCo description (see the module docstring).

    Args:
        robot: The true robot, built from a URDF.
        camera: Intrinsics: the image size and the field of view.
        diameter: Sphere diameter D [m].
        obstacles: The obstacles on the floor.

    Raises:
        UrdfError: If the robot has no URDF or MuJoCo cannot read it.
    """
    try:
        spec = mujoco.MjSpec.from_string(_visual_urdf(robot))
    except ValueError as err:
        raise UrdfError(robot.source, f"MuJoCo cannot read the URDF: {err}") from err
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    files = {mesh.name: mesh.file for mesh in spec.meshes}
    undrawable = []
    for body in spec.bodies:
        body.mass, body.inertia, body.fullinertia = 1.0, [1.0, 1.0, 1.0], [np.nan] * 6
        # MuJoCo's URDF importer puts visual geometry in group 1, collision geometry in 0
        geoms = [(geom, _drawable(geom, files)) for geom in body.geoms]
        drawn = 1 if all(ok for geom, ok in geoms if geom.group == 1) else 0
        if not drawn:
            undrawable.append(body.name)
        for geom, ok in geoms:
            if geom.group != drawn or not ok:
                spec.delete(geom)
            else:
                geom.group = 0
    for mesh in list(spec.meshes):  # an unused mesh is still read when the model compiles
        if not mesh.file.lower().endswith(MESH_FORMATS):
            spec.delete(mesh)
        else:  # drawn, never weighed: a flat mesh's volume must not stop the build (Stretch)
            mesh.inertia = mujoco.mjtMeshInertia.mjMESH_INERTIA_SHELL
    if undrawable:
        more = len(undrawable) - 5
        links = ", ".join(undrawable[:5]) + (f" and {more} more" if more > 0 else "")
        warnings.warn(
            f"{robot.source}: rendered camera: links {links} are drawn with "
            f"their collision geometry: MuJoCo reads {', '.join(MESH_FORMATS)} meshes, not "
            f"their visual meshes ({_formats(files)})",
            PbvsWarning,
            stacklevel=2,
        )
    # the model's planar joint sits at the URDF's root link: the drive footprint of a
    # differential drive, the platform's own root link on a holonomic base
    spec.worldbody.first_body().add_freejoint(name=frames.DRIVE_FOOTPRINT)
    for index, hue in enumerate(SPHERE_HUES):
        body = spec.worldbody.add_body(name=f"sphere{index}", mocap=True)
        body.add_geom(
            type=mujoco.mjtGeom.mjGEOM_SPHERE,
            size=[diameter / 2, 0, 0],
            rgba=sphere_rgba(hue),
            material=_matte(spec, f"sphere{index}"),
        )
    for obstacle in obstacles:
        _add_obstacle(spec, obstacle)
    _add_floor(spec)
    spec.worldbody.add_light(
        pos=[0.0, 0.0, 6.0], dir=[0.2, 0.1, -1.0], type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
        castshadow=False, diffuse=[0.6, 0.6, 0.6], specular=[0.1, 0.1, 0.1],
    )  # fmt: skip
    spec.visual.headlight.ambient = [0.3, 0.3, 0.3]
    spec.visual.headlight.diffuse = [0.3, 0.3, 0.3]
    spec.worldbody.add_camera(name="eye", fovy=camera_fovy(camera))
    spec.visual.global_.offwidth, spec.visual.global_.offheight = camera.width, camera.height
    # no multisampling: 2.5x faster, and the sphere's binary mask then has its centroid at the
    # silhouette's centre within 0.03 px (with MuJoCo's 4 samples, 0.3 px off vertically)
    spec.visual.quality.offsamples = 0
    spec.stat.extent = 1.0  # znear is a fraction of the extent
    spec.visual.map.znear = NEAR_CLIP
    spec.visual.map.zfar = 500.0
    return spec


def camera_fovy(camera: CameraIntrinsics) -> float:
    r"""MuJoCo's vertical field of view [deg]: ``2 atan(H / (2 f))``."""
    return float(np.degrees(2.0 * np.arctan(0.5 * camera.height / camera.focal_px)))


def _add_obstacle(spec: mujoco.MjSpec, obstacle: Obstacle) -> None:
    """A cylinder or a box standing on the floor."""
    half = obstacle.height / 2
    if isinstance(obstacle, CircleObstacle):
        spec.worldbody.add_geom(
            type=mujoco.mjtGeom.mjGEOM_CYLINDER, size=[obstacle.radius, half, 0],
            pos=[obstacle.x, obstacle.y, half], rgba=OBSTACLE_RGBA,
        )  # fmt: skip
    elif isinstance(obstacle, BoxObstacle):
        yaw = obstacle.yaw
        spec.worldbody.add_geom(
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[obstacle.size_x / 2, obstacle.size_y / 2, half],
            pos=[obstacle.x, obstacle.y, half],
            quat=[np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)],
            rgba=OBSTACLE_RGBA,
        )
    else:
        raise RenderingUnavailable(f"no drawing for obstacle {obstacle!r}")


def _matte(spec: mujoco.MjSpec, name: str) -> str:
    """A material without specular highlight (a highlight is not the sphere's colour)."""
    spec.add_material(name=name, specular=0.0, shininess=0.0)
    return name


def _add_floor(spec: mujoco.MjSpec) -> None:
    """A plane with a 0.5 m checker of two greys."""
    spec.add_texture(
        name="floor", type=mujoco.mjtTexture.mjTEXTURE_2D,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, rgb1=FLOOR_RGB[0], rgb2=FLOOR_RGB[1],
        width=64, height=64,
    )  # fmt: skip
    material = spec.add_material(name="floor", texrepeat=[1.0, 1.0], texuniform=True)
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "floor"
    spec.worldbody.add_geom(
        type=mujoco.mjtGeom.mjGEOM_PLANE, size=[0.0, 0.0, 1.0], material="floor"
    )


class SceneRenderer:
    """Draws the scene from the camera with MuJoCo (see the module docstring).

    Args:
        robot: The true robot, built from a URDF.
        camera: Intrinsics.
        diameter: Sphere diameter D [m].
        obstacles: The obstacles on the floor.

    Raises:
        UrdfError: If the robot has no URDF or MuJoCo cannot read it.
        RenderingUnavailable: If MuJoCo cannot open an offscreen OpenGL context.
    """

    def __init__(
        self,
        robot: MobileManipulator,
        camera: CameraIntrinsics,
        diameter: float,
        obstacles: list[Obstacle],
    ) -> None:
        self.robot, self.camera, self.diameter = robot, camera, diameter
        try:
            self.model = scene_spec(robot, camera, diameter, obstacles).compile()
        except ValueError as err:  # a mesh MuJoCo cannot read or build
            raise UrdfError(
                robot.source, f"rendered camera: MuJoCo cannot build the scene: {err}"
            ) from err
        self.data = mujoco.MjData(self.model)
        model = self.model
        self._arm_qpos = np.array([model.joint(n).qposadr[0] for n in robot.arm_joint_names])
        self._light = model.light_diffuse.copy(), model.vis.headlight.diffuse.copy()
        self._ambient = model.vis.headlight.ambient.copy()
        try:
            self.renderer = mujoco.Renderer(model, camera.height, camera.width)
        except Exception as err:  # MuJoCo raises several types when no GL context opens
            raise RenderingUnavailable(
                f"MuJoCo cannot render offscreen with MUJOCO_GL="
                f"{os.environ.get('MUJOCO_GL', '')!r} ({err}); set MUJOCO_GL=egl (Debian: "
                "apt-get install libegl1 libegl-mesa0) or osmesa (libosmesa6) before MuJoCo "
                "is imported"
            ) from err

    def render(
        self,
        q: np.ndarray,
        camera_pose: pin.SE3,
        centres: np.ndarray,
        light: float = 1.0,
    ) -> np.ndarray:
        """The image seen from ``camera_pose``.

        Args:
            q: Configuration of the robot (controller's model). Shape (nq,).
            camera_pose: ``world_T_camera`` of the optical frame.
            centres: Sphere centres [m], upper first. Shape (2, 3).
            light: Factor on the lights' intensity (1: as built).

        Returns:
            RGB image, ``uint8``. Shape (H, W, 3).
        """
        model, data = self.model, self.data
        yaw = np.arctan2(q[3], q[2])
        data.qpos[:7] = [q[0], q[1], 0.0, np.cos(yaw / 2), 0.0, 0.0, np.sin(yaw / 2)]
        data.qpos[self._arm_qpos] = self.robot.arm_positions(q)
        data.mocap_pos[:] = centres
        model.cam_pos[0] = camera_pose.translation
        rotation = camera_pose.rotation @ OPTICAL_TO_MUJOCO
        mujoco.mju_mat2Quat(model.cam_quat[0], rotation.reshape(-1))
        lights, headlight = self._light
        model.light_diffuse[:] = light * lights
        model.vis.headlight.diffuse[:] = light * headlight
        model.vis.headlight.ambient[:] = light * self._ambient
        mujoco.mj_kinematics(model, data)
        mujoco.mj_camlight(model, data)
        self.renderer.update_scene(data, camera="eye")
        return self.renderer.render()

    def robot_in_view(
        self, q: np.ndarray, camera_pose: pin.SE3, centres: np.ndarray
    ) -> dict[str, float]:
        """The share of the image each of the robot's own links covers, seen from ``camera_pose``.

        Args:
            q: Configuration of the robot (controller's model). Shape (nq,).
            camera_pose: ``world_T_camera`` of the optical frame.
            centres: Sphere centres [m], upper first. Shape (2, 3).

        Returns:
            Link name to its share of the pixels (0-1), largest first; links not seen omitted.
        """
        self.render(q, camera_pose, centres)
        self.renderer.enable_segmentation_rendering()
        try:
            segments = self.renderer.render()
        finally:
            self.renderer.disable_segmentation_rendering()
        model = self.model
        geoms = segments[..., 0][segments[..., 1] == mujoco.mjtObj.mjOBJ_GEOM]
        shares: dict[str, float] = {}
        for geom, pixels in zip(*np.unique(geoms, return_counts=True), strict=True):
            body = model.geom_bodyid[geom]
            name = model.body(body).name
            if body == 0 or name.startswith("sphere"):  # the floor, the obstacles, the target
                continue
            shares[name] = shares.get(name, 0.0) + pixels / segments[..., 0].size
        return dict(sorted(shares.items(), key=lambda item: -item[1]))

    def close(self) -> None:
        """Release the OpenGL context."""
        self.renderer.close()


SELF_VIEW_WARNING = 0.2
"""Share of the image covered by the robot's own links at the start above which the rendered
camera warns (TIAGo Pro's camera in ``arm_right_tool_link`` sees 82 % of its own hand)."""


def warn_self_view(shares: dict[str, float], source: str) -> None:
    """Warn, naming ``source`` and the links, if the robot covers much of its camera's view.

    Args:
        shares: Link name to its share of the image (:meth:`SceneRenderer.robot_in_view`).
        source: The robot's file, named in the warning.
    """
    total = sum(shares.values())
    if total <= SELF_VIEW_WARNING:
        return
    seen = ", ".join(f"{name} {100 * share:.0f} %" for name, share in list(shares.items())[:4])
    warnings.warn(
        f"{source}: rendered camera: at the start the robot's own links cover "
        f"{100 * total:.0f} % of the image ({seen}); the target behind them is not seen. Move "
        "the camera where it sees past the robot (camera_link, camera_pose)",
        PbvsWarning,
        stacklevel=2,
    )

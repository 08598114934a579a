"""
Offscreen MuJoCo rendering of the cell for dual_arm_render: cameras, GL backends, the scene.

SceneRenderer builds the simulator's own model of the cell (sim_bridge.scene.build_spec) for a
scenario, adds lights, a sky, a floor and an offscreen buffer of the video's size, and renders
the arms and the object at given joint positions and pose. The GL backend is MUJOCO_GL (EGL by
default; OSMesa and GLFW also work); gl_backend() must run before mujoco is first imported.
"""

from dataclasses import dataclass
import math
import os

from dual_arm_control.core.exceptions import DualArmControlError, InputError
import numpy as np

GL_BACKENDS = ('egl', 'osmesa', 'glfw')
MAX_SCENE_GEOMS = 2000


@dataclass(frozen=True)
class CameraView:
    """A free camera: azimuth and elevation [deg], distance [m] to lookat (3,) in the world."""

    azimuth: float
    elevation: float
    distance: float
    lookat: tuple


# World frame: x forward to the workspace, z up, left arm at +y. MuJoCo's azimuth is the
# heading the camera looks along (0: +x, 90: +y); negative elevation looks down.
CAMERA_PRESETS = {
    'perspective': CameraView(150.0, -24.0, 1.9, (0.50, 0.0, 0.38)),
    'front': CameraView(180.0, -15.0, 2.2, (0.50, 0.0, 0.45)),
    'side': CameraView(90.0, -10.0, 2.2, (0.60, 0.0, 0.45)),
    'top': CameraView(0.0, -89.0, 2.2, (0.50, 0.0, 0.30)),
}
DEFAULT_CAMERA = 'perspective'


def parse_camera(text):
    """
    Return the CameraView of a preset name or of 'azimuth,elevation,distance[,x,y,z]'.

    Angles in degrees, distance and lookat in metres (default lookat: the preset's). Raises
    InputError naming the accepted forms.
    """
    if text in CAMERA_PRESETS:
        return CAMERA_PRESETS[text]
    try:
        values = [float(value) for value in text.split(',')]
    except ValueError:
        values = []
    if len(values) not in (3, 6) or not all(math.isfinite(value) for value in values):
        raise InputError(f'--camera {text!r}: give one of {sorted(CAMERA_PRESETS)} or '
                         "'azimuth,elevation,distance[,x,y,z]' (deg, deg, m, m)")
    if values[2] <= 0.0:
        raise InputError(f'--camera {text!r}: distance must be > 0 m, got {values[2]}')
    lookat = tuple(values[3:]) if len(values) == 6 else CAMERA_PRESETS[DEFAULT_CAMERA].lookat
    return CameraView(values[0], values[1], values[2], lookat)


class OffscreenUnavailable(DualArmControlError, RuntimeError):
    """No offscreen OpenGL context can be created with the chosen backend."""


def gl_backend():
    """
    Return the OpenGL backend to render with: MUJOCO_GL, set to 'egl' if the user has not set it.

    Call before MuJoCo is first imported: mujoco picks its own GL module at import from
    MUJOCO_GL. Raises InputError for a backend that cannot render offscreen here.
    """
    backend = os.environ.setdefault('MUJOCO_GL', 'egl').lower().strip()
    if backend not in GL_BACKENDS:
        raise InputError(f'MUJOCO_GL={backend!r} cannot render offscreen; use one of '
                         f'{GL_BACKENDS}')
    return backend


def _import_mujoco(backend):
    """Import mujoco, which loads the MUJOCO_GL module at import (fails if it is missing)."""
    try:
        import mujoco
    except Exception as error:  # noqa: B902 (a missing GL library surfaces as any error)
        raise OffscreenUnavailable(f'{backend}: importing mujoco failed: '
                                   f'{type(error).__name__}: {error}') from error
    return mujoco


def _gl_context(backend, width, height):
    """Create and make current a GL context of the backend for a width x height buffer."""
    try:
        if backend == 'egl':
            from mujoco.egl import GLContext
        elif backend == 'osmesa':
            from mujoco.osmesa import GLContext
        else:
            from mujoco.glfw import GLContext
        context = GLContext(width, height)
        context.make_current()
    except Exception as error:  # noqa: B902 (any failure of the GL stack means unavailable)
        raise OffscreenUnavailable(f'{backend}: {type(error).__name__}: {error}') from error
    return context


def _video_spec(spec, width, height):
    """Add lights, a sky, a checker floor and a width x height offscreen buffer to a spec."""
    import mujoco
    spec.visual.global_.offwidth = max(int(width), spec.visual.global_.offwidth)
    spec.visual.global_.offheight = max(int(height), spec.visual.global_.offheight)
    spec.visual.headlight.ambient = [0.35, 0.35, 0.35]
    spec.visual.headlight.diffuse = [0.45, 0.45, 0.45]
    spec.visual.headlight.specular = [0.1, 0.1, 0.1]
    spec.visual.quality.shadowsize = 2048
    key = spec.worldbody.add_light(name='video_key', pos=[0.9, -0.8, 2.6],
                                   dir=[-0.25, 0.25, -1.0])
    key.type = mujoco.mjtLightType.mjLIGHT_DIRECTIONAL
    key.castshadow = True
    key.diffuse = [0.5, 0.5, 0.5]
    key.ambient = [0.0, 0.0, 0.0]
    key.specular = [0.2, 0.2, 0.2]
    spec.add_texture(name='video_sky', type=mujoco.mjtTexture.mjTEXTURE_SKYBOX,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_GRADIENT, rgb1=[0.75, 0.82, 0.90],
                     rgb2=[0.25, 0.30, 0.38], width=256, height=256)
    spec.add_texture(name='video_floor', type=mujoco.mjtTexture.mjTEXTURE_2D,
                     builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER, rgb1=[0.42, 0.44, 0.48],
                     rgb2=[0.36, 0.38, 0.42], width=256, height=256)
    material = spec.add_material(name='video_floor')
    material.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = 'video_floor'
    material.texrepeat = [6.0, 6.0]
    spec.geom('floor').material = 'video_floor'
    return spec


class SceneRenderer:
    """
    Offscreen renderer of the cell for a scenario at a fixed width x height and camera.

    set_state() places the arms and the object; render() returns the (height, width, 3) uint8
    RGB image, optionally with text in the top-left corner. Use as a context manager or call
    close(): the GL resources belong to the thread that created them.
    """

    def __init__(self, scenario, width, height, camera, backend=None, cell=None):
        """Build the scene of a Scenario; camera: CameraView; backend: MUJOCO_GL name."""
        backend = backend or gl_backend()
        mujoco = _import_mujoco(backend)
        from dual_arm_control.description.cell import load_cell
        from sim_bridge.scene import build_spec, scene_index
        self._mujoco = mujoco
        self.width, self.height = int(width), int(height)
        spec = _video_spec(build_spec(cell or load_cell(), scenario.object), width, height)
        self.model = spec.compile()
        self.index = scene_index(self.model)
        self.data = mujoco.MjData(self.model)
        self._initial_qpos = self.model.qpos0.copy()   # the object at the scenario's pose
        mujoco.mj_forward(self.model, self.data)
        self._gl = _gl_context(backend, self.width, self.height)
        self._context = None
        try:
            self._context = mujoco.MjrContext(self.model, _font_scale(self.height))
            mujoco.mjr_setBuffer(mujoco.mjtFramebuffer.mjFB_OFFSCREEN, self._context)
            if self._context.currentBuffer != mujoco.mjtFramebuffer.mjFB_OFFSCREEN:
                raise OffscreenUnavailable('the GL context has no offscreen framebuffer')
        except Exception:
            self.close()
            raise
        self._scene = mujoco.MjvScene(self.model, maxgeom=MAX_SCENE_GEOMS)
        self._option = mujoco.MjvOption()
        self._perturb = mujoco.MjvPerturb()
        self._camera = mujoco.MjvCamera()
        self._camera.type = mujoco.mjtCamera.mjCAMERA_FREE
        self.set_camera(camera)
        self._viewport = mujoco.MjrRect(0, 0, self.width, self.height)
        self._pixels = np.empty((self.height, self.width, 3), dtype=np.uint8)

    def __enter__(self):
        return self

    def __exit__(self, *exc_info):
        self.close()

    def set_camera(self, camera):
        """Aim the free camera (CameraView)."""
        self._camera.azimuth = camera.azimuth
        self._camera.elevation = camera.elevation
        self._camera.distance = camera.distance
        self._camera.lookat[:] = camera.lookat

    def set_state(self, q, qd=None, object_position=None, object_quat_xyzw=None):
        """
        Place the arms at q {arm: (7,)} [rad] and the object at its pose, then run mj_forward.

        qd {arm: (7,)} [rad/s] sets joint velocities (for tool_speed); the object keeps the
        scenario's initial pose when object_position is None.
        """
        mujoco = self._mujoco
        qpos = self._initial_qpos.copy()
        self.data.qvel[:] = 0.0
        for arm, index in self.index.arms.items():
            qpos[index.qpos] = q[arm]
            if qd is not None:
                self.data.qvel[index.dof] = qd[arm]
        if object_position is not None:
            adr = self.index.object_qpos
            qpos[adr:adr + 3] = object_position
            x, y, z, w = object_quat_xyzw
            qpos[adr + 3:adr + 7] = [w, x, y, z]
        self.data.qpos[:] = qpos
        mujoco.mj_forward(self.model, self.data)

    def tool_speed(self, arm):
        """Return the speed [m/s] of an arm's tool point at the current joint velocities."""
        velocity = np.zeros(6)
        self._mujoco.mj_objectVelocity(self.model, self.data, self._mujoco.mjtObj.mjOBJ_SITE,
                                       self.index.arms[arm].tool_site, velocity, 0)
        return float(np.linalg.norm(velocity[3:]))

    def render(self, overlay=None):
        """
        Return the current scene as a new (height, width, 3) uint8 RGB image.

        overlay: (titles, values), two newline-separated columns of text drawn top left.
        """
        mujoco = self._mujoco
        self._gl.make_current()
        mujoco.mjv_updateScene(self.model, self.data, self._option, self._perturb,
                               self._camera, mujoco.mjtCatBit.mjCAT_ALL, self._scene)
        mujoco.mjr_render(self._viewport, self._scene, self._context)
        if overlay is not None:
            mujoco.mjr_overlay(mujoco.mjtFont.mjFONT_NORMAL, mujoco.mjtGridPos.mjGRID_TOPLEFT,
                               self._viewport, overlay[0], overlay[1], self._context)
        mujoco.mjr_readPixels(self._pixels, None, self._viewport, self._context)
        return np.flipud(self._pixels).copy()

    def close(self):
        """Free the MuJoCo render context and the GL context (idempotent)."""
        if getattr(self, '_context', None) is not None:
            self._gl.make_current()
            self._context.free()
            self._context = None
        if getattr(self, '_gl', None) is not None:
            self._gl.free()
            self._gl = None


def _font_scale(height):
    """Return the MjrContext font scale [%] for a frame height [px] (text readable, not huge)."""
    if height < 400:
        return 100
    return 150 if height < 800 else 200

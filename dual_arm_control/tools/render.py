"""
dual_arm_render: render a recorded episode (MCAP bag) to an MP4 or a GIF with MuJoCo offscreen.

The scene is the simulator's own model of the cell (sim_bridge.scene.build_spec) for the
episode's scenario, with lights and an offscreen buffer of the video's size added. Each frame
shows the arms at the recorded joint positions and the object at its recorded pose (ground truth,
else the tracker's estimate), interpolated linearly at the frame's sim time; --speed 0.5 plays
the episode at half speed. Optional text overlays: sim time, phase, tool and object speeds.

Rendering needs no display or GPU: MUJOCO_GL=egl by default (Mesa llvmpipe works), OSMesa as
fallback. The scenario is read from the bag (its 'dual_arm_control' metadata, written by
`dual_arm_bringup --record`, else a recorded 'scenario' parameter event) unless --scenario is
given. Exit codes: 0 written, 1 no offscreen OpenGL, 2 user error,
130 interrupted (no partial file is left).
"""

import argparse
from dataclasses import dataclass, field
import math
import os
from pathlib import Path
import subprocess
import sys
import time

from dual_arm_control import contract
from dual_arm_control.bags import BagError
from dual_arm_control.bags.reader import bag_files
from dual_arm_control.bags.writer import METADATA_NAME
from dual_arm_control.core.exceptions import DualArmControlError, InputError
from dual_arm_control.nodes.bag_record import message_class
from dual_arm_control.scenario import load_scenario
from mcap.exceptions import McapError
from mcap.reader import make_reader
import numpy as np
from rclpy.serialization import deserialize_message

EXIT_NO_OPENGL = 1
EXIT_USER_ERROR = 2
EXIT_INTERRUPTED = 130
GL_BACKENDS = ('egl', 'osmesa', 'glfw')
FORMATS = {'.mp4': 'mp4', '.gif': 'gif'}
OVERLAY_ITEMS = ('time', 'phase', 'speeds')
PARAMETER_EVENTS_TOPIC = '/parameter_events'
SCENARIO_PARAMETER = 'scenario'
MAX_SCENE_GEOMS = 2000
# Frames sampled to build the GIF's shared palette (one palette keeps static pixels identical
# from frame to frame, so each GIF frame stores only the region that changed).
GIF_PALETTE_SAMPLES = 8
MP4_QUALITY = 7                  # imageio-ffmpeg quality, 0 (worst) - 10 (best)
# A phase stamped within this of a frame's time is shown in that frame [s].
_TIME_EPSILON = 1e-9


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


# -- the bag -----------------------------------------------------------------------------------

@dataclass(frozen=True)
class EpisodeRecord:
    """
    Time-indexed signals of a recorded episode; times are sim seconds (message header stamps).

    joint_time {arm: (N,)}; joint_position and joint_velocity {arm: (N, 7)} [rad], [rad/s]
    in URDF order A1..A7; object_time (M,); object_position (M, 3) [m]; object_quat_xyzw
    (M, 4); object_velocity (M, 3) [m/s], world frame; object_source: the topic the object
    came from (None: no object pose in the bag); phase_time (K,) and phase (K,) names;
    scenario: scenario file recorded in the bag, or None.
    """

    joint_time: dict
    joint_position: dict
    joint_velocity: dict
    object_time: np.ndarray = field(default_factory=lambda: np.zeros(0))
    object_position: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    object_quat_xyzw: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    object_velocity: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    object_source: str = None
    phase_time: np.ndarray = field(default_factory=lambda: np.zeros(0))
    phase: tuple = ()
    scenario: str = None

    @property
    def start(self):
        """First sim time at which both arms have a joint sample [s]."""
        return max(float(times[0]) for times in self.joint_time.values())

    @property
    def end(self):
        """Last sim time at which both arms have a joint sample [s]."""
        return min(float(times[-1]) for times in self.joint_time.values())

    def state_at(self, t):
        """Return the FrameState at sim time t [s], interpolated between samples."""
        q = {arm: _interpolate(self.joint_time[arm], self.joint_position[arm], t)
             for arm in self.joint_time}
        qd = {arm: _interpolate(self.joint_time[arm], self.joint_velocity[arm], t)
              for arm in self.joint_time}
        if self.object_source is None:
            position = quat = object_speed = None
        else:
            position = _interpolate(self.object_time, self.object_position, t)
            quat = _interpolate_quaternion(self.object_time, self.object_quat_xyzw, t)
            object_speed = float(np.linalg.norm(
                _interpolate(self.object_time, self.object_velocity, t)))
        index = int(np.searchsorted(self.phase_time, t + _TIME_EPSILON, side='right')) - 1
        phase = self.phase[index] if index >= 0 else None
        return FrameState(t, q, qd, position, quat, object_speed, phase)


@dataclass(frozen=True)
class FrameState:
    """What one frame shows: sim time [s], joints, object pose (None: scenario pose), phase."""

    t: float
    q: dict
    qd: dict
    object_position: np.ndarray = None
    object_quat_xyzw: np.ndarray = None
    object_speed: float = None
    phase: str = None


def _interpolate(times, values, t):
    """Return values (N, k) linearly interpolated at t, held beyond the first and last sample."""
    index = int(np.searchsorted(times, t, side='right'))
    if index == 0:
        return values[0].copy()
    if index == len(times):
        return values[-1].copy()
    t0, t1 = times[index - 1], times[index]
    weight = (t - t0) / (t1 - t0) if t1 > t0 else 0.0
    return values[index - 1] + weight * (values[index] - values[index - 1])


def _interpolate_quaternion(times, quats, t):
    """Return the normalised linear interpolation of unit quaternions (N, 4) at t."""
    index = int(np.searchsorted(times, t, side='right'))
    if index == 0 or index == len(times):
        quat = quats[0 if index == 0 else -1]
        return quat / np.linalg.norm(quat)
    q0, q1 = quats[index - 1], quats[index]
    if np.dot(q0, q1) < 0.0:
        q1 = -q1
    t0, t1 = times[index - 1], times[index]
    weight = (t - t0) / (t1 - t0) if t1 > t0 else 0.0
    quat = q0 + weight * (q1 - q0)
    return quat / np.linalg.norm(quat)


def _stamp(msg):
    return msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec


def _bag_files(path):
    """Return the files of a (possibly split) bag or rosbag2 folder; InputError if none."""
    try:
        return bag_files(path)
    except BagError as error:
        raise InputError(str(error)) from None


def _recorded_scenario(files):
    """Return the scenario named in the bag's METADATA_NAME metadata record, or None."""
    for path in files:
        try:
            with open(path, 'rb') as stream:
                for record in make_reader(stream).iter_metadata():
                    if record.name == METADATA_NAME and record.metadata.get('scenario'):
                        return record.metadata['scenario']
        except (McapError, OSError, ValueError, EOFError):
            return None
    return None


def _messages(files, topics):
    """Yield (topic, message, log_time_ns) of the given topics, in log-time order per file."""
    classes = {}
    for path in files:
        try:
            with open(path, 'rb') as stream:
                for schema, channel, message in make_reader(stream).iter_messages(
                        topics=topics, log_time_order=True):
                    if schema is None:
                        continue
                    if schema.name not in classes:
                        classes[schema.name] = message_class(schema.name)
                    yield (channel.topic, deserialize_message(message.data, classes[schema.name]),
                           message.log_time)
        except (McapError, OSError, ValueError, EOFError) as error:
            raise InputError(f'bag {path} cannot be read: {error}') from None


def _scenario_from_parameter_event(msg):
    for parameter in list(msg.new_parameters) + list(msg.changed_parameters):
        if parameter.name == SCENARIO_PARAMETER and parameter.value.string_value:
            return parameter.value.string_value
    return None


def read_episode(path):
    """
    Read an episode's joint states, object pose, phase and scenario from an MCAP bag.

    Joint states from /<arm>/joint_states (required); the object from the ground-truth topic,
    else the tracker's /object/state; the phase from /dual_arm/phase. Split bags
    (<stem>_1.mcap, ...) are read as one. Returns an EpisodeRecord. Raises InputError naming
    the file and the problem (missing file, unreadable bag, no joint states of an arm).
    """
    files = _bag_files(path)
    joint_topics = {contract.JOINT_STATES.resolved(arm): arm for arm in contract.ARMS}
    object_topics = (contract.GROUND_TRUTH_OBJECT.name, contract.OBJECT_STATE.name)
    topics = (list(joint_topics) + list(object_topics)
              + [contract.PHASE.name, PARAMETER_EVENTS_TOPIC])
    joints = {arm: [] for arm in contract.ARMS}
    objects = {topic: [] for topic in object_topics}
    phases = []
    scenario_parameter = None
    for topic, msg, log_time in _messages(files, topics):
        if topic in joint_topics:
            arm = joint_topics[topic]
            joints[arm].append(_joint_sample(topic, msg, arm, log_time))
        elif topic in objects:
            pose, twist = msg.pose.pose, msg.twist.twist
            quat = (pose.orientation.x, pose.orientation.y, pose.orientation.z,
                    pose.orientation.w)
            if np.linalg.norm(quat) < 0.5:
                continue  # no estimate yet (a zero quaternion)
            objects[topic].append((_stamp(msg), log_time,
                                   (pose.position.x, pose.position.y, pose.position.z),
                                   quat, (twist.linear.x, twist.linear.y, twist.linear.z)))
        elif topic == contract.PHASE.name:
            for status in msg.status:
                if status.name == contract.PHASE_STATUS_NAME:
                    phases.append((_stamp(msg), log_time, status.message))
        elif topic == PARAMETER_EVENTS_TOPIC:
            scenario_parameter = _scenario_from_parameter_event(msg) or scenario_parameter
    for arm, samples in joints.items():
        if not samples:
            raise InputError(f'bag {path} has no {contract.JOINT_STATES.resolved(arm)} '
                             'messages: nothing to render')
    use_log_time = all(sample[0] == joints[contract.ARMS[0]][0][0]
                       for samples in joints.values() for sample in samples)
    joint_time, joint_position, joint_velocity = {}, {}, {}
    for arm, samples in joints.items():
        times = _times(samples, use_log_time)
        order = np.argsort(times, kind='stable')
        joint_time[arm] = times[order]
        joint_position[arm] = np.array([sample[2] for sample in samples])[order]
        velocity = np.array([sample[3] for sample in samples])[order]
        if np.isnan(velocity).any():
            velocity = (np.gradient(joint_position[arm], joint_time[arm], axis=0)
                        if len(samples) > 1 and np.all(np.diff(joint_time[arm]) > 0.0)
                        else np.zeros_like(joint_position[arm]))
        joint_velocity[arm] = velocity
    record = {'joint_time': joint_time, 'joint_position': joint_position,
              'joint_velocity': joint_velocity,
              'scenario': _recorded_scenario(files) or scenario_parameter}
    source = next((topic for topic in object_topics if objects[topic]), None)
    if source is not None:
        samples = objects[source]
        times = _times(samples, use_log_time)
        order = np.argsort(times, kind='stable')
        record.update(object_source=source, object_time=times[order],
                      object_position=np.array([s[2] for s in samples])[order],
                      object_quat_xyzw=np.array([s[3] for s in samples])[order],
                      object_velocity=np.array([s[4] for s in samples])[order])
    if phases:
        times = _times(phases, use_log_time)
        order = np.argsort(times, kind='stable')
        record.update(phase_time=times[order], phase=tuple(phases[i][2] for i in order))
    return EpisodeRecord(**record)


def _times(samples, use_log_time):
    """Return the sample times [s]: header stamps, or log times if the stamps are all equal."""
    if use_log_time:
        return np.array([1e-9 * sample[1] for sample in samples])
    return np.array([sample[0] for sample in samples])


def _joint_sample(topic, msg, arm, log_time):
    """Return (stamp, log_time, position (7,), velocity (7,) or NaN) of a JointState."""
    names = contract.joint_names(arm)
    if list(msg.name) and set(names) <= set(msg.name) and len(msg.position) == len(msg.name):
        order = [list(msg.name).index(name) for name in names]
    elif not list(msg.name) and len(msg.position) == len(names):
        order = list(range(len(names)))
    else:
        raise InputError(f'{topic}: joint state names {list(msg.name)} with '
                         f'{len(msg.position)} positions do not cover {names}')
    position = np.array(msg.position)[order]
    velocity = (np.array(msg.velocity)[order] if len(msg.velocity) == len(msg.position)
                else np.full(len(names), np.nan))
    return _stamp(msg), log_time, position, velocity


# -- rendering ---------------------------------------------------------------------------------

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


def overlay_text(state, items, speed_factor, tool_speeds):
    """
    Return (titles, values) of the overlay items for a FrameState.

    items: subset of OVERLAY_ITEMS; tool_speeds {arm: m/s}; speed_factor: playback speed.
    """
    rows = []
    if 'time' in items:
        playback = '' if speed_factor == 1.0 else f' ({speed_factor:g}x)'
        rows.append(('t', f'{state.t:6.3f} s{playback}'))
    if 'phase' in items:
        rows.append(('phase', state.phase or '-'))
    if 'speeds' in items:
        for arm in contract.ARMS:
            rows.append((f'{arm} tool', f'{tool_speeds[arm]:.2f} m/s'))
        rows.append(('object', '-' if state.object_speed is None
                     else f'{state.object_speed:.2f} m/s'))
    return '\n'.join(row[0] for row in rows), '\n'.join(row[1] for row in rows)


def frame_times(start, end, fps, speed):
    """
    Return the sim times [s] of the frames of [start, end] at fps frames per video second.

    One video second shows speed sim seconds; frames k = 0, 1, ... at start + k speed / fps
    up to end (inclusive within 1e-9 s).
    """
    step = speed / fps
    count = int(math.floor((end - start) / step + 1e-9)) + 1
    return start + step * np.arange(count)


def episode_frames(record, renderer, times, overlay_items=(), speed_factor=1.0):
    """Yield the rendered (height, width, 3) frame of the record at each sim time."""
    for t in times:
        state = record.state_at(float(t))
        renderer.set_state(state.q, state.qd, state.object_position, state.object_quat_xyzw)
        overlay = None
        if overlay_items:
            tool_speeds = {arm: renderer.tool_speed(arm) for arm in contract.ARMS}
            overlay = overlay_text(state, overlay_items, speed_factor, tool_speeds)
        yield renderer.render(overlay)


# -- video files -------------------------------------------------------------------------------

class _Mp4Writer:
    """H.264 MP4 through imageio-ffmpeg's bundled ffmpeg, frames streamed."""

    def __init__(self, path, width, height, fps):
        import imageio_ffmpeg
        self._path = Path(path)
        self._writer = imageio_ffmpeg.write_frames(
            str(path), (width, height), fps=fps, codec='libx264', quality=MP4_QUALITY,
            pix_fmt_out='yuv420p', macro_block_size=2, ffmpeg_log_level='error')
        self._writer.send(None)

    def append(self, frame):
        self._writer.send(np.ascontiguousarray(frame))

    def close(self):
        self._writer.close()

    def abort(self):
        """Stop ffmpeg and remove the partial file."""
        self._writer.close()
        self._path.unlink(missing_ok=True)


class _GifWriter:
    """
    Looping GIF through Pillow with one palette for all frames.

    palette_frames: a few representative frames the 256-colour palette is built from.
    """

    def __init__(self, path, fps, palette_frames):
        from PIL import Image
        self._image = Image
        self._path = path
        self._fps = fps
        mosaic = Image.fromarray(np.concatenate(list(palette_frames), axis=0))
        self._palette = mosaic.quantize(colors=256, method=Image.Quantize.MEDIANCUT,
                                        dither=Image.Dither.NONE)
        self._frames = []

    def append(self, frame):
        self._frames.append(self._image.fromarray(frame).quantize(
            palette=self._palette, dither=self._image.Dither.NONE))

    def abort(self):
        """Drop the frames; nothing was written."""
        self._frames = []

    def close(self):
        if self._frames:
            # GIF delays are whole centiseconds: alternate them so frame k starts at k / fps.
            centiseconds = np.round(100.0 * np.arange(len(self._frames) + 1) / self._fps)
            self._frames[0].save(self._path, save_all=True, append_images=self._frames[1:],
                                 duration=(10 * np.diff(centiseconds)).astype(int).tolist(),
                                 loop=0, optimize=False, disposal=1)


# -- command line ------------------------------------------------------------------------------

@dataclass(frozen=True)
class RenderSummary:
    """What render_video wrote: frames, sim interval [s], wall time per frame [s], bytes."""

    path: Path
    frames: int
    start: float
    end: float
    seconds_per_frame: float
    size_bytes: int


def render_video(record, scenario, output, fps=30.0, width=640, height=480, speed=1.0,
                 start=None, end=None, camera=None, overlay_items=(), backend=None,
                 progress=False):
    """
    Render a recorded episode into output (.mp4 or .gif); return a RenderSummary.

    record: EpisodeRecord; scenario: Scenario (builds the scene); fps [1/s]; speed: sim
    seconds per video second; start/end: sim interval [s] (default: the whole record);
    camera: CameraView (default preset 'perspective'); overlay_items: subset of OVERLAY_ITEMS.
    Raises InputError for a bad output name or interval, OffscreenUnavailable without OpenGL.
    """
    output = Path(output)
    kind = FORMATS.get(output.suffix.lower())
    if kind is None:
        raise InputError(f'output {output}: unknown video type {output.suffix!r}; use one of '
                         f'{sorted(FORMATS)}')
    if kind == 'mp4' and (width % 2 or height % 2):
        raise InputError(f'MP4 needs an even width and height, got {width}x{height}')
    start = record.start if start is None else float(start)
    end = record.end if end is None else float(end)
    if not record.start - 1e-6 <= start < end <= record.end + 1e-6:
        raise InputError(f'--start {start:g} / --end {end:g} s: need start < end within the '
                         f'recorded joint states [{record.start:g}, {record.end:g}] s')
    times = frame_times(start, end, fps, speed)
    unknown = sorted(set(overlay_items) - set(OVERLAY_ITEMS))
    if unknown:
        raise InputError(f'unknown overlay item(s) {unknown}; choose from {OVERLAY_ITEMS}')
    try:
        output.parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(f'cannot create the folder of {output}: {error}') from None
    camera = camera or CAMERA_PRESETS[DEFAULT_CAMERA]
    with SceneRenderer(scenario, width, height, camera, backend) as renderer:
        frames = episode_frames(record, renderer, times, overlay_items, speed)
        if kind == 'gif':
            samples = times[np.linspace(0, len(times) - 1,
                                        min(GIF_PALETTE_SAMPLES, len(times))).astype(int)]
            writer = _GifWriter(output, fps, episode_frames(record, renderer, samples,
                                                            overlay_items, speed))
        else:
            writer = _Mp4Writer(output, width, height, fps)
        started = time.perf_counter()
        try:
            for frame in _progress(frames, len(times), progress):
                writer.append(frame)
        except BaseException:
            writer.abort()
            raise
        writer.close()
        elapsed = time.perf_counter() - started
    return RenderSummary(output, len(times), start, end, elapsed / len(times),
                         output.stat().st_size)


def _progress(frames, total, enabled):
    """Wrap the frame iterator in a tqdm bar on stderr when enabled and tqdm is installed."""
    if not enabled:
        return frames
    try:
        from tqdm import tqdm
    except ImportError:
        return frames
    return tqdm(frames, total=total, unit='frame', file=sys.stderr, leave=False, disable=None)


def _positive(kind, low, high):
    def parse(text):
        try:
            value = kind(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'not a number: {text!r}') from None
        if not low < value <= high:
            raise argparse.ArgumentTypeError(f'{value} is not in ({low}, {high}]')
        return value
    return parse


def _overlay_items(text):
    items = [item.strip() for item in text.split(',') if item.strip()]
    if items == ['all']:
        return OVERLAY_ITEMS
    if items == ['none']:
        return ()
    unknown = sorted(set(items) - set(OVERLAY_ITEMS))
    if unknown:
        raise argparse.ArgumentTypeError(f'unknown item(s) {unknown}; use a comma-separated '
                                         f"subset of {OVERLAY_ITEMS}, 'all' or 'none'")
    return tuple(items)


def build_parser():
    """Return the argument parser of dual_arm_render."""
    parser = argparse.ArgumentParser(
        prog='dual_arm_render', description=__doc__.strip().split('\n')[0].split(': ', 1)[1],
        epilog='Camera presets: ' + ', '.join(
            f'{name} (azimuth {view.azimuth:g}, elevation {view.elevation:g}, distance '
            f'{view.distance:g})' for name, view in CAMERA_PRESETS.items()))
    parser.add_argument('bag', type=Path, help='episode bag (.mcap, from --record)')
    parser.add_argument('-o', '--output', type=Path, required=True,
                        help='video file: .mp4 (H.264) or .gif')
    parser.add_argument('--scenario',
                        help='scenario file or name (default: the one recorded in the bag)')
    parser.add_argument('--fps', type=_positive(float, 0.0, 120.0), default=30.0,
                        help='video frames per second (default 30)')
    parser.add_argument('--width', type=_positive(int, 15, 4096), default=640,
                        help='frame width [px] (default 640)')
    parser.add_argument('--height', type=_positive(int, 15, 4096), default=480,
                        help='frame height [px] (default 480)')
    parser.add_argument('--speed', type=_positive(float, 0.0, 100.0), default=1.0,
                        help='playback speed: sim seconds per video second (0.5: slow motion)')
    parser.add_argument('--start', type=float, help='first sim time [s] (default: bag start)')
    parser.add_argument('--end', type=float, help='last sim time [s] (default: bag end)')
    parser.add_argument('--camera', default=DEFAULT_CAMERA,
                        help=f"preset {sorted(CAMERA_PRESETS)} or 'azimuth,elevation,distance"
                        "[,x,y,z]' in deg, deg, m, m (default perspective)")
    parser.add_argument('--overlay', type=_overlay_items, default=(),
                        help=f"comma-separated text overlays from {OVERLAY_ITEMS}, or 'all' "
                        '(default none)')
    parser.add_argument('--quiet', action='store_true', help='no progress bar or summary')
    return parser


def _resolve_scenario(args, record):
    """Load --scenario, else the scenario the bag names; raise InputError if neither works."""
    source = args.scenario or record.scenario
    if source is None:
        raise InputError(f'bag {args.bag} does not name its scenario; pass --scenario')
    try:
        return load_scenario(source)
    except DualArmControlError as error:
        origin = '--scenario' if args.scenario else 'scenario recorded in the bag'
        raise InputError(f'{origin} {source}: {error}') from None


def _osmesa_fallback(argv, egl_error):
    """Re-run this command with MUJOCO_GL=osmesa (PyOpenGL binds one platform per process)."""
    print(f'dual_arm_render: EGL unavailable ({egl_error}); retrying with OSMesa',
          file=sys.stderr)
    env = dict(os.environ, MUJOCO_GL='osmesa', PYOPENGL_PLATFORM='osmesa')
    return subprocess.run([sys.executable, '-m', 'dual_arm_control.tools.render', *argv],
                          env=env, check=False).returncode


def main(argv=None):
    """Render a bag into a video; return 0, 1 (no offscreen OpenGL) or 2 (user error)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    args = build_parser().parse_args(argv)
    user_backend = 'MUJOCO_GL' in os.environ
    try:
        backend = gl_backend()
        camera = parse_camera(args.camera)
        record = read_episode(args.bag)
        scenario = _resolve_scenario(args, record)
        summary = render_video(record, scenario, args.output, args.fps, args.width,
                               args.height, args.speed, args.start, args.end, camera,
                               args.overlay, backend, progress=not args.quiet)
    except OffscreenUnavailable as error:
        if not user_backend and backend == 'egl':
            return _osmesa_fallback(argv, error)
        print(f'dual_arm_render: cannot render offscreen: {error}; install Mesa EGL '
              '(libegl1) or OSMesa (libosmesa6), or set MUJOCO_GL', file=sys.stderr)
        return EXIT_NO_OPENGL
    except DualArmControlError as error:
        print(f'dual_arm_render: {error}', file=sys.stderr)
        return EXIT_USER_ERROR
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED
    if not args.quiet:
        print(f'dual_arm_render: wrote {summary.path}: {summary.frames} frames '
              f'{args.width}x{args.height} at {args.fps:g} fps, sim {summary.start:.3f}-'
              f'{summary.end:.3f} s at {args.speed:g}x, {summary.size_bytes / 1e6:.2f} MB, '
              f'{1e3 * summary.seconds_per_frame:.0f} ms/frame')
    return 0


if __name__ == '__main__':
    sys.exit(main())

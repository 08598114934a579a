"""
dual_arm_render: episode bags rendered offscreen (EGL / llvmpipe) into GIF and MP4.

A synthetic 0.5 s bag moves left A1 by 0.8 rad, right A4 by 0.5 rad and lifts and turns the
object, at 100 Hz; the phase switches from 'reach' to 'contact' at 0.25 s and the scenario is
named in /parameter_events as the bridge's parameter. Videos are 160 x 120 at 10 fps.
"""

from pathlib import Path

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from dual_arm_control import contract
from dual_arm_control.bags.writer import BagWriter
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.scenario import load_scenario
from dual_arm_control.tools import episode_bag, episode_video, render, scene_renderer
import imageio_ffmpeg
import mujoco
from nav_msgs.msg import Odometry
import numpy as np
from PIL import Image, ImageSequence
import pytest
from rcl_interfaces.msg import Parameter, ParameterEvent, ParameterType, ParameterValue
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

REPOSITORY = Path(__file__).resolve().parents[1]
SCENARIO = REPOSITORY / 'config' / 'scenarios' / 'paper_toss.yaml'
DURATION = 0.5              # [s]
PERIOD = 0.01               # bag sample period [s]
PHASE_SWITCH = 0.25         # [s]
WIDTH, HEIGHT, FPS = 160, 120, 10.0
LEFT_A1_TRAVEL = 0.8        # [rad]
RIGHT_A4_TRAVEL = 0.5       # [rad]
OBJECT_LIFT = 0.1           # [m]
OBJECT_TURN = 0.3           # yaw [rad]
LOG_TIME_OFFSET_NS = 1_700_000_000_000_000_000


def joint_positions(scenario, t):
    """Return the synthetic joint positions {arm: (7,)} [rad] at t [s]."""
    fraction = t / DURATION
    q = {arm: np.array(scenario.initial_configuration[arm], dtype=float)
         for arm in contract.ARMS}
    q['left'][0] += LEFT_A1_TRAVEL * fraction
    q['right'][3] += RIGHT_A4_TRAVEL * fraction
    return q


def object_pose(scenario, t):
    """Return the synthetic object (position (3,) [m], quaternion (x, y, z, w)) at t [s]."""
    fraction = t / DURATION
    position = np.array(scenario.object.position) + [0.0, 0.0, OBJECT_LIFT * fraction]
    yaw = float(scenario.object.yaw) + OBJECT_TURN * fraction
    return position, np.array([0.0, 0.0, np.sin(0.5 * yaw), np.cos(0.5 * yaw)])


def stamp(t):
    """Return the builtin_interfaces Time of t [s]."""
    nanoseconds = int(round(t * 1e9))
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def write_bag(path, scenario, with_joints=True):
    """Write the synthetic episode into an MCAP bag at path."""
    with BagWriter(path, compression='none') as writer:
        topics = {contract.CLOCK.name: contract.CLOCK,
                  contract.GROUND_TRUTH_OBJECT.name: contract.GROUND_TRUTH_OBJECT,
                  contract.PHASE.name: contract.PHASE}
        if with_joints:
            topics.update({contract.JOINT_STATES.resolved(arm): contract.JOINT_STATES
                           for arm in contract.ARMS})
        for name, topic in topics.items():
            writer.add_topic(name, topic.msg_type, topic.qos)
        writer.add_topic(episode_bag.PARAMETER_EVENTS_TOPIC, ParameterEvent, contract.MONITOR_QOS)
        event = ParameterEvent(node='/sim_bridge', new_parameters=[Parameter(
            name='scenario', value=ParameterValue(type=ParameterType.PARAMETER_STRING,
                                                  string_value=str(scenario.path)))])
        writer.write(episode_bag.PARAMETER_EVENTS_TOPIC, serialize_message(event),
                     LOG_TIME_OFFSET_NS)
        for k in range(int(round(DURATION / PERIOD)) + 1):
            t = k * PERIOD
            log_time = LOG_TIME_OFFSET_NS + int(round(t * 1e9)) + 1
            writer.write(contract.CLOCK.name, serialize_message(Clock(clock=stamp(t))),
                         log_time)
            if with_joints:
                for arm, q in joint_positions(scenario, t).items():
                    msg = JointState(name=contract.joint_names(arm), position=q.tolist(),
                                     velocity=[0.0] * 7)
                    msg.header.stamp = stamp(t)
                    writer.write(contract.JOINT_STATES.resolved(arm), serialize_message(msg),
                                 log_time)
            position, quat = object_pose(scenario, t)
            odometry = Odometry()
            odometry.header.stamp = stamp(t)
            pose = odometry.pose.pose
            pose.position.x, pose.position.y, pose.position.z = position.tolist()
            (pose.orientation.x, pose.orientation.y, pose.orientation.z,
             pose.orientation.w) = quat.tolist()
            odometry.twist.twist.linear.z = OBJECT_LIFT / DURATION
            writer.write(contract.GROUND_TRUTH_OBJECT.name, serialize_message(odometry),
                         log_time)
            phase = DiagnosticArray(status=[DiagnosticStatus(
                name=contract.PHASE_STATUS_NAME,
                message='reach' if t < PHASE_SWITCH - 1e-9 else 'contact')])
            phase.header.stamp = stamp(t)
            writer.write(contract.PHASE.name, serialize_message(phase), log_time)


@pytest.fixture(scope='module')
def scenario():
    """Return the paper_toss Scenario."""
    return load_scenario(SCENARIO)


@pytest.fixture(scope='module')
def bag(tmp_path_factory, scenario):
    """Return the path of the synthetic episode bag."""
    path = tmp_path_factory.mktemp('render') / 'episode.mcap'
    write_bag(path, scenario)
    return path


@pytest.fixture(scope='module')
def renderer(scenario):
    """Return a SceneRenderer of paper_toss at the test size, default camera."""
    scene_renderer.gl_backend()
    camera = scene_renderer.CAMERA_PRESETS[scene_renderer.DEFAULT_CAMERA]
    with scene_renderer.SceneRenderer(scenario, WIDTH, HEIGHT, camera) as scene:
        yield scene


def direct_render(scene, scenario, t):
    """Render the synthetic state at t by writing qpos straight into the model's data."""
    qpos = scene.data.qpos
    for arm, q in joint_positions(scenario, t).items():
        qpos[scene.index.arms[arm].qpos] = q
    position, (x, y, z, w) = object_pose(scenario, t)
    adr = scene.index.object_qpos
    qpos[adr:adr + 7] = [*position, w, x, y, z]
    scene.data.qvel[:] = 0.0
    mujoco.mj_forward(scene.model, scene.data)
    return scene.render()


def changed_region(first, second, threshold=30):
    """Return the boolean (H, W) mask where two RGB frames differ by more than threshold."""
    difference = np.abs(first.astype(int) - second.astype(int)).max(axis=2)
    return difference > threshold


def test_frame_times_cover_the_interval_at_the_playback_speed():
    """Frame k shows sim time start + k speed / fps; the end is included when it falls on one."""
    times = episode_video.frame_times(1.0, 1.5, 10.0, 0.5)
    np.testing.assert_allclose(times, 1.0 + 0.05 * np.arange(11), atol=1e-12)
    assert len(episode_video.frame_times(0.0, DURATION, FPS, 1.0)) == 6


def test_camera_presets_and_custom_views():
    """Presets by name; 'az,el,dist[,x,y,z]' as numbers; anything else is a clear InputError."""
    assert scene_renderer.parse_camera('side') == scene_renderer.CAMERA_PRESETS['side']
    view = scene_renderer.parse_camera('30,-20,1.5,0.4,0.1,0.3')
    assert (view.azimuth, view.elevation, view.distance, view.lookat) == (
        30.0, -20.0, 1.5, (0.4, 0.1, 0.3))
    for text in ('sideways', '30,-20', '30,-20,0', 'a,b,c'):
        with pytest.raises(InputError, match='camera'):
            scene_renderer.parse_camera(text)


def test_read_episode_orders_joints_and_finds_the_scenario(bag, scenario):
    """Joint arrays in A1..A7 order at the stamps, object and phase series, scenario path."""
    record = episode_bag.read_episode(bag)
    assert record.scenario == str(scenario.path)
    assert record.object_source == contract.GROUND_TRUTH_OBJECT.name
    assert (record.start, record.end) == (0.0, pytest.approx(DURATION))
    state = record.state_at(0.125)   # between samples 0.12 and 0.13 s
    expected = joint_positions(scenario, 0.125)
    for arm in contract.ARMS:
        np.testing.assert_allclose(state.q[arm], expected[arm], atol=1e-12)
    position, quat = object_pose(scenario, 0.125)
    np.testing.assert_allclose(state.object_position, position, atol=1e-12)
    np.testing.assert_allclose(state.object_quat_xyzw, quat, atol=1e-5)  # nlerp over 0.006 rad
    assert state.object_speed == pytest.approx(OBJECT_LIFT / DURATION)
    assert record.state_at(PHASE_SWITCH - 0.001).phase == 'reach'
    assert record.state_at(PHASE_SWITCH).phase == 'contact'


def test_bag_frame_is_identical_to_a_direct_render_of_the_same_qpos(bag, scenario, renderer):
    """At a sample time the rendered bag state and the directly written qpos give equal pixels."""
    record = episode_bag.read_episode(bag)
    for t in (0.0, 0.3):
        from_bag = next(episode_video.episode_frames(record, renderer, [t]))
        direct = direct_render(renderer, scenario, t)
        assert from_bag.shape == (HEIGHT, WIDTH, 3)
        assert np.array_equal(from_bag, direct)
    assert changed_region(direct_render(renderer, scenario, 0.0),
                          direct_render(renderer, scenario, 0.3)).sum() > 100


def test_overlay_draws_text_top_left_and_follows_the_phase(bag, renderer):
    """The overlay changes pixels only in a top band (one text row), differently per phase."""
    record = episode_bag.read_episode(bag)
    plain, reach, contact = (
        next(episode_video.episode_frames(record, renderer, [t], items))
        for t, items in ((0.2, ()), (0.2, ('phase',)), (0.3, ('phase',))))
    text = changed_region(plain, reach, threshold=20)
    assert text.sum() > 50
    rows, columns = np.nonzero(text)
    assert rows.min() < 10 and rows.max() < HEIGHT // 3 and columns.min() < 10
    plain_contact = next(episode_video.episode_frames(record, renderer, [0.3]))
    reach_text = changed_region(plain, reach, 20)
    contact_text = changed_region(plain_contact, contact, 20)
    assert (reach_text != contact_text).sum() > 10


@pytest.mark.parametrize('suffix', ['.gif', '.mp4'])
def test_cli_writes_a_video_with_one_frame_per_step_and_the_motion(tmp_path, bag, scenario,
                                                                   renderer, capsys, suffix):
    """
    The file holds duration * fps + 1 frames; first and last differ where the arm moved.

    The region is where direct renders of the first and last state differ; outside it the
    frames agree (same palette in the GIF; H.264 noise in the MP4), so the motion shown is
    the bag's and nothing else changes.
    """
    output = tmp_path / f'episode{suffix}'
    status = render.main([str(bag), '-o', str(output), '--width', str(WIDTH), '--height',
                          str(HEIGHT), '--fps', str(FPS), '--quiet'])
    assert status == 0, capsys.readouterr().err
    expected_frames = int(DURATION * FPS) + 1
    if suffix == '.gif':
        with Image.open(output) as gif:
            frames = [np.array(frame.convert('RGB')) for frame in ImageSequence.Iterator(gif)]
            durations = [frame.info['duration'] for frame in ImageSequence.Iterator(gif)]
        assert durations == [100] * expected_frames   # 1 / FPS each, in whole centiseconds
        outside_tolerance = 2.0
    else:
        reader = imageio_ffmpeg.read_frames(str(output))
        width, height = next(reader)['size']
        frames = [np.frombuffer(data, np.uint8).reshape(height, width, 3) for data in reader]
        assert imageio_ffmpeg.count_frames_and_secs(str(output))[0] == expected_frames
        outside_tolerance = 3.0
    assert len(frames) == expected_frames
    assert abs(len(frames) - DURATION * FPS) <= 1
    assert frames[0].shape == (HEIGHT, WIDTH, 3)
    moved = changed_region(direct_render(renderer, scenario, 0.0),
                           direct_render(renderer, scenario, DURATION))
    first, last = (frame.astype(float) for frame in (frames[0], frames[-1]))
    difference = np.abs(first - last).max(axis=2)
    assert moved.sum() > 100
    assert difference[moved].mean() > 40.0
    assert difference[~moved].mean() < outside_tolerance


def test_cli_slow_motion_interval_and_overlay(tmp_path, bag, capsys):
    """--speed 0.5 over [0.1, 0.3] s at 10 fps gives 0.2 / 0.05 + 1 frames; overlay accepted."""
    output = tmp_path / 'slow.gif'
    status = render.main([str(bag), '-o', str(output), '--width', '96', '--height', '72',
                          '--fps', '10', '--speed', '0.5', '--start', '0.1', '--end', '0.3',
                          '--overlay', 'all', '--camera', 'top', '--scenario', 'paper_toss'])
    assert status == 0, capsys.readouterr().err
    with Image.open(output) as gif:
        assert gif.n_frames == 5


def test_cli_bag_without_joint_states_is_a_one_line_error(tmp_path, scenario, capsys):
    """No /left/joint_states: exit 2 and one stderr line naming the topic, no traceback."""
    path = tmp_path / 'no_joints.mcap'
    write_bag(path, scenario, with_joints=False)
    status = render.main([str(path), '-o', str(tmp_path / 'x.gif'), '--quiet'])
    error = capsys.readouterr().err
    assert status == 2
    assert error.count('\n') == 1 and 'Traceback' not in error
    assert '/left/joint_states' in error
    assert not (tmp_path / 'x.gif').exists()


@pytest.mark.parametrize('arguments, message', [
    (['-o', 'video.avi'], 'unknown video type'),
    (['-o', 'video.mp4', '--width', '161'], 'even width'),
    (['-o', 'video.gif', '--start', '0.4', '--end', '0.2'], 'start < end'),
    (['-o', 'video.gif', '--camera', 'behind'], 'camera'),
    (['-o', 'video.gif', '--scenario', 'no_such_scenario'], 'no_such_scenario'),
])
def test_cli_user_errors_are_one_line(tmp_path, bag, capsys, arguments, message):
    """Bad output type, odd MP4 size, empty interval, bad camera, bad scenario: exit 2."""
    arguments = [str(tmp_path / a) if a.startswith('video') else a for a in arguments]
    status = render.main([str(bag), '--quiet', *arguments])
    error = capsys.readouterr().err
    assert status == 2
    assert error.count('\n') == 1 and message in error


def test_cli_missing_bag_is_a_one_line_error(tmp_path, capsys):
    """A bag path that does not exist: exit 2, one line naming it."""
    status = render.main([str(tmp_path / 'absent.mcap'), '-o', str(tmp_path / 'x.gif')])
    error = capsys.readouterr().err
    assert status == 2 and error.count('\n') == 1 and 'absent.mcap' in error

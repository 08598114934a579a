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

This module is the command line; the bag is read by tools/episode_bag.py, the scene drawn by
tools/scene_renderer.py and the video written by tools/episode_video.py.
"""

import argparse
import os
from pathlib import Path
import subprocess
import sys

from dual_arm_control.core.exceptions import DualArmControlError, InputError
from dual_arm_control.scenario import load_scenario
from dual_arm_control.tools.episode_bag import read_episode
from dual_arm_control.tools.episode_video import OVERLAY_ITEMS, render_video
from dual_arm_control.tools.scene_renderer import (CAMERA_PRESETS, DEFAULT_CAMERA, gl_backend,
                                                   OffscreenUnavailable, parse_camera)

EXIT_NO_OPENGL = 1
EXIT_USER_ERROR = 2
EXIT_INTERRUPTED = 130


def _positive(kind, low, high):
    """Return an argparse type: a number of kind in (low, high]."""
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
    """Return the overlay items of --overlay: a comma-separated subset, 'all' or 'none'."""
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

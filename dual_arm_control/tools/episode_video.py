"""
Videos of recorded episodes for dual_arm_render: frame times, overlays and MP4 / GIF files.

render_video renders an EpisodeRecord with a SceneRenderer frame by frame at the frame's sim
time (--speed scales sim time to video time) and streams the frames into an H.264 MP4
(imageio-ffmpeg) or a looping GIF with one shared palette (Pillow). An interrupted render
leaves no partial file.
"""

from dataclasses import dataclass
import math
from pathlib import Path
import sys
import time

from dual_arm_control import contract
from dual_arm_control.core.exceptions import InputError
from dual_arm_control.tools.scene_renderer import CAMERA_PRESETS, DEFAULT_CAMERA, SceneRenderer
import numpy as np

FORMATS = {'.mp4': 'mp4', '.gif': 'gif'}
OVERLAY_ITEMS = ('time', 'phase', 'speeds')
# Frames sampled to build the GIF's shared palette (one palette keeps static pixels identical
# from frame to frame, so each GIF frame stores only the region that changed).
GIF_PALETTE_SAMPLES = 8
MP4_QUALITY = 7                  # imageio-ffmpeg quality, 0 (worst) - 10 (best)


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
        """Encode one (height, width, 3) uint8 RGB frame."""
        self._writer.send(np.ascontiguousarray(frame))

    def close(self):
        """Finish the file."""
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
        """Quantize one (height, width, 3) uint8 RGB frame to the shared palette and keep it."""
        self._frames.append(self._image.fromarray(frame).quantize(
            palette=self._palette, dither=self._image.Dither.NONE))

    def abort(self):
        """Drop the frames; nothing was written."""
        self._frames = []

    def close(self):
        """Write the kept frames as a looping GIF (nothing if there are none)."""
        if self._frames:
            # GIF delays are whole centiseconds: alternate them so frame k starts at k / fps.
            centiseconds = np.round(100.0 * np.arange(len(self._frames) + 1) / self._fps)
            self._frames[0].save(self._path, save_all=True, append_images=self._frames[1:],
                                 duration=(10 * np.diff(centiseconds)).astype(int).tolist(),
                                 loop=0, optimize=False, disposal=1)


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

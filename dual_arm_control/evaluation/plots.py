"""Episode plots from a ground-truth trajectory (PNG, matplotlib, no display needed)."""

from pathlib import Path

from dual_arm_control.contract import ARMS
import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402, I100  (the backend is chosen before pyplot loads)
import numpy as np  # noqa: E402, I100

ARM_COLOURS = {'left': 'tab:red', 'right': 'tab:blue'}


def _mark_events(axis, events):
    """Draw vertical lines at the named event times (contact cyan, release magenta)."""
    styles = {'contact': 'c', 'release': 'm'}
    for name, time in events.items():
        if time is not None:
            axis.axvline(time, color=styles.get(name, 'k'), linestyle='--', linewidth=1.0,
                         label=name)


def plot_tool_speeds(data, events, path):
    """Tool-centre speed norms and components of both arms over time (paper Figure 6)."""
    figure, axes = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    t = data['t']
    for arm in ARMS:
        velocity = data[f'{arm}_tool_velocity']
        axes[0].plot(t, np.linalg.norm(velocity, axis=1), color=ARM_COLOURS[arm],
                     label=f'{arm} |v|')
        for component, style in zip('xyz', ('-', '--', ':')):
            axes[1].plot(t, velocity[:, 'xyz'.index(component)], style, color=ARM_COLOURS[arm],
                         label=f'{arm} v{component}')
    for axis in axes:
        _mark_events(axis, events)
        axis.grid(True, alpha=0.3)
    axes[0].set_ylabel('tool speed [m/s]')
    axes[1].set_ylabel('tool velocity [m/s]')
    axes[1].set_xlabel('sim time [s]')
    axes[0].legend(loc='upper right', fontsize=8)
    axes[1].legend(loc='upper right', fontsize=7, ncol=2)
    save_figure(figure, path)


def plot_object_motion(data, events, path):
    """Object speed, velocity and position over time (paper Figure 7a)."""
    figure, axes = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    t = data['t']
    velocity = data['object_velocity']
    position = data['object_position']
    axes[0].plot(t, np.linalg.norm(velocity, axis=1), 'k')
    for index, colour in enumerate(('tab:red', 'tab:green', 'tab:blue')):
        axes[1].plot(t, velocity[:, index], color=colour, label='xyz'[index])
        axes[2].plot(t, position[:, index], color=colour, label='xyz'[index])
    labels = ('object speed [m/s]', 'object velocity [m/s]', 'object position [m]')
    for axis, label in zip(axes, labels):
        _mark_events(axis, events)
        axis.set_ylabel(label)
        axis.grid(True, alpha=0.3)
    axes[1].legend(loc='upper right', fontsize=8)
    axes[2].set_xlabel('sim time [s]')
    save_figure(figure, path)


def plot_trajectories_3d(data, path):
    """3D paths of both tools and the object (paper Figure 7b)."""
    figure = plt.figure(figsize=(7, 6))
    axis = figure.add_subplot(projection='3d')
    for arm in ARMS:
        p = data[f'{arm}_tool_position']
        axis.plot(p[:, 0], p[:, 1], p[:, 2], color=ARM_COLOURS[arm], label=f'{arm} tool')
    p = data['object_position']
    axis.plot(p[:, 0], p[:, 1], p[:, 2], color='k', label='object')
    axis.set_xlabel('x [m]')
    axis.set_ylabel('y [m]')
    axis.set_zlabel('z [m]')
    axis.legend(fontsize=8)
    save_figure(figure, path)


def plot_tool_drift(data, path):
    """Distance of each tool from its initial position over time (hold test)."""
    figure, axis = plt.subplots(figsize=(8, 4))
    t = data['t']
    for arm in ARMS:
        p = data[f'{arm}_tool_position']
        axis.plot(t, 1000.0 * np.linalg.norm(p - p[0], axis=1), color=ARM_COLOURS[arm],
                  label=arm)
    axis.set_xlabel('sim time [s]')
    axis.set_ylabel('tool drift [mm]')
    axis.grid(True, alpha=0.3)
    axis.legend()
    save_figure(figure, path)


def save_figure(figure, path, dpi=110):
    """Write the figure to path (folders created) and free it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    figure.tight_layout()
    figure.savefig(path, dpi=dpi)
    plt.close(figure)

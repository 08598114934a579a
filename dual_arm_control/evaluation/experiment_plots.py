"""Plots of the paper experiments (Figures 6-10 analogues), PNG through matplotlib's Agg."""

from dual_arm_control.contract import ARMS
from dual_arm_control.evaluation import plots as episode_plots
import matplotlib
matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402, I100  (the backend is chosen before pyplot loads)
import numpy as np  # noqa: E402, I100

TASK_COLOURS = {'pick_and_place': 'tab:blue', 'pick_and_toss': 'tab:red'}
TASK_LABELS = {'pick_and_place': 'pick-and-place', 'pick_and_toss': 'pick-and-toss'}
CLOSEUP_MARGIN = 0.25


def _mark(axis, events):
    for name, colour in (('contact', 'c'), ('release', 'm')):
        if events.get(name) is not None:
            axis.axvline(events[name], color=colour, linestyle='--', linewidth=1.0, label=name)


def _table_outline(axis, cell, **style):
    table = cell.front_table
    x0, y0 = table.center[:2] - 0.5 * table.size[:2]
    axis.add_patch(plt.Rectangle((x0, y0), table.size[0], table.size[1], fill=False, **style))


def figure6_tool_speeds(data, events, path):
    """Tool speed norms and velocity components of both arms, whole episode (Figure 6 top)."""
    episode_plots.plot_tool_speeds(data, events, path)


def figure6_closeup(data, events, path):
    """Per arm: speed norm, and velocity components from before contact to after release."""
    figure, axes = plt.subplots(2, 2, figsize=(11, 6))
    t = data['t']
    begin = (events['contact'] or t[0]) - CLOSEUP_MARGIN
    end = (events['release'] or t[-1]) + CLOSEUP_MARGIN
    window = (t >= begin) & (t <= end)
    for column, arm in enumerate(ARMS):
        velocity = data[f'{arm}_tool_velocity']
        axes[0, column].plot(t, np.linalg.norm(velocity, axis=1), color='k', label='|v|')
        for index, colour in enumerate(('tab:red', 'tab:green', 'tab:blue')):
            axes[1, column].plot(t[window], velocity[window, index], color=colour,
                                 label='v' + 'xyz'[index])
        axes[0, column].set_title(f'{arm} arm ({"iiwa7" if arm == "left" else "iiwa14"})')
        axes[0, column].set_ylabel('tool speed [m/s]')
        axes[1, column].set_ylabel('tool velocity [m/s]')
        axes[1, column].set_xlabel('time from episode start [s]')
        for axis in axes[:, column]:
            _mark(axis, events)
            axis.grid(True, alpha=0.3)
            axis.legend(fontsize=7, loc='upper right')
    episode_plots.save_figure(figure, path, dpi=100)


def figure7_object_motion(data, events, path):
    """Object speed, velocity and position with contact and release marked (Figure 7a)."""
    episode_plots.plot_object_motion(data, events, path)


def figure7_trajectories(data, path):
    """3D paths of both tools and the object (Figure 7b)."""
    episode_plots.plot_trajectories_3d(data, path)


def figure8_top_view(grid, joint, toss_mask, added, hull, landings, cell, path):
    """Joint reachable space, tossing extension, landings and the table, top view (Fig. 8)."""
    figure, axis = plt.subplots(figsize=(7, 7))
    xs, ys = grid.centres()
    image = np.zeros(joint.shape)
    image[joint] = 1.0
    image[added] = 2.0
    colours = matplotlib.colors.ListedColormap(['white', 'orchid', 'lightskyblue'])
    axis.pcolormesh(np.append(xs - 0.5 * grid.cell, xs[-1] + 0.5 * grid.cell),
                    np.append(ys - 0.5 * grid.cell, ys[-1] + 0.5 * grid.cell), image.T,
                    cmap=colours, vmin=0.0, vmax=2.0, edgecolors='none')
    if len(hull) >= 3:
        closed = np.vstack((hull, hull[:1]))
        axis.plot(closed[:, 0], closed[:, 1], color='tab:blue', linewidth=1.0,
                  label='landing hull')
    if len(landings):
        axis.plot(landings[:, 0], landings[:, 1], 'o', color='c', markersize=4,
                  markeredgecolor='k', markeredgewidth=0.3, label='landings')
    _table_outline(axis, cell, edgecolor='k', linestyle='--', label='front table')
    for arm in ARMS:
        base = cell.arm(arm).base_position
        axis.plot(base[0], base[1], 's', color='k', markersize=7)
    axis.plot([], [], 's', color='orchid', label='joint reachable space')
    axis.plot([], [], 's', color='lightskyblue', label='tossing extension')
    axis.set_xlim(grid.x0, min(grid.x0 + grid.nx * grid.cell, 1.2))
    axis.set_ylim(max(grid.y0, -0.8), min(grid.y0 + grid.ny * grid.cell, 0.8))
    axis.set_aspect('equal')
    axis.set_xlabel('x [m]')
    axis.set_ylabel('y [m]')
    axis.legend(fontsize=8, loc='upper right')
    axis.grid(True, alpha=0.3)
    episode_plots.save_figure(figure, path, dpi=100)


def figure8_trajectories(flights, reachable, cell, path, z_band, points_per_arm=2500):
    """3D flights of the tossed object over the arms' reachable positions (Figure 8 left)."""
    figure = plt.figure(figsize=(8, 7))
    axis = figure.add_subplot(projection='3d')
    for arm, colour in (('left', 'tab:green'), ('right', 'tab:red')):
        points = reachable[arm]
        points = points[(points[:, 0] >= 0.0) & (points[:, 2] >= z_band[0])
                        & (points[:, 2] <= z_band[1])]
        shown = points[::max(1, len(points) // points_per_arm)]
        axis.scatter(shown[:, 0], shown[:, 1], shown[:, 2], s=2, alpha=0.25, color=colour,
                     label=f'{arm} tool, pad facing the object')
    for index, flight in enumerate(flights):
        axis.plot(flight[:, 0], flight[:, 1], flight[:, 2], color='tab:blue', linewidth=1.0,
                  label='tossed object centre' if index == 0 else None)
        axis.scatter(*flight[-1], color='c', s=10, edgecolor='k', linewidth=0.3)
    table = cell.front_table
    x0, y0 = table.center[:2] - 0.5 * table.size[:2]
    x1, y1 = min(x0 + table.size[0], 1.2), y0 + table.size[1]
    axis.plot([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], [table.top_height] * 5, 'k--',
              linewidth=0.8, label='front table top')
    axis.set_xlim(0.0, 1.2)
    axis.set_ylim(-0.8, 0.8)
    axis.set_zlim(0.0, 1.0)
    axis.set_xlabel('x [m]')
    axis.set_ylabel('y [m]')
    axis.set_zlabel('z [m]')
    axis.view_init(elev=30, azim=-120)
    axis.legend(fontsize=7, loc='upper left')
    episode_plots.save_figure(figure, path, dpi=100)


def _speed_norms(series, arm):
    runs = np.array([np.linalg.norm(data[f'{arm}_tool_velocity'], axis=1) for data in series])
    return series[0]['t'], runs.mean(axis=0), runs.std(axis=0)


def figure9_speeds(series, path, speed):
    """Mean and std of both arms' tool speeds, place (top) and toss (bottom) (Figure 9a)."""
    figure, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for axis, task in zip(axes, ('pick_and_place', 'pick_and_toss')):
        for arm, colour in (('left', 'tab:red'), ('right', 'tab:blue')):
            t, mean, std = _speed_norms(series[task], arm)
            axis.plot(t, mean, color=colour, label=f'{arm} arm')
            axis.fill_between(t, mean - std, mean + std, color=colour, alpha=0.25)
        axis.set_title(f'{TASK_LABELS[task]} at {speed:g} m/s ({len(series[task])} runs)')
        axis.set_ylabel('tool speed [m/s]')
        axis.grid(True, alpha=0.3)
        axis.legend(fontsize=8)
    axes[-1].set_xlabel('time from episode start [s]')
    episode_plots.save_figure(figure, path, dpi=100)


def figure9_energy(series, path, speed, cumulative_energy):
    """Mean and std of the cumulative energy of each arm, place vs toss (Figure 9b)."""
    figure, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for axis, arm in zip(axes, ARMS):
        for task, runs in series.items():
            curves = np.array([cumulative_energy(data['t'], data[f'{arm}_tau'],
                                                 data[f'{arm}_dq']) for data in runs])
            t = runs[0]['t']
            mean, std = curves.mean(axis=0), curves.std(axis=0)
            axis.plot(t, mean, color=TASK_COLOURS[task], label=TASK_LABELS[task])
            axis.fill_between(t, mean - std, mean + std, color=TASK_COLOURS[task], alpha=0.25)
        axis.set_title(f'{arm} arm, {speed:g} m/s')
        axis.set_xlabel('time from episode start [s]')
        axis.grid(True, alpha=0.3)
        axis.legend(fontsize=8)
    axes[0].set_ylabel('energy |tau . dq| integrated [J]')
    episode_plots.save_figure(figure, path, dpi=100)


def figure10_bars(summary, path):
    """Cycle time (a) and total energy (b) of both tasks over the task speeds (Figure 10)."""
    figure, axes = plt.subplots(1, 2, figsize=(11, 4))
    speeds = np.array([row['speed'] for row in summary])
    width = 0.04
    for offset, task in ((-0.5, 'pick_and_place'), (0.5, 'pick_and_toss')):
        for axis, key, label in ((axes[0], 'cycle_time', 'cycle time [s]'),
                                 (axes[1], 'energy', 'energy, both arms [J]')):
            means = [row[task][key]['mean'] for row in summary]
            stds = [row[task][key]['std'] for row in summary]
            present = [m is not None for m in means]
            axis.bar(speeds[present] + offset * width, [m for m in means if m is not None],
                     width, yerr=[s for s in stds if s is not None], capsize=3,
                     color=TASK_COLOURS[task], label=TASK_LABELS[task])
            axis.set_ylabel(label)
    for axis, title in zip(axes, ('(a) task duration', '(b) energy expenditure')):
        axis.set_xlabel('task speed [m/s]')
        axis.set_xticks(speeds)
        axis.set_title(title)
        axis.grid(True, axis='y', alpha=0.3)
        axis.legend(fontsize=8)
    episode_plots.save_figure(figure, path, dpi=100)


def landing_errors(rows, cell, path):
    """Targets, measured landings and their errors over the front table (experiment 5)."""
    figure, (top, bars) = plt.subplots(1, 2, figsize=(12, 5))
    _table_outline(top, cell, edgecolor='k', linestyle='--', label='front table')
    for index, row in enumerate(rows):
        target = row['target']
        top.plot(target[0], target[1], 'x', color='k', markersize=8,
                 label='target' if index == 0 else None)
        if row['landing_position'] is not None:
            landing = row['landing_position']
            top.plot(landing[0], landing[1], 'o', color='tab:green' if row['hit']
                     else 'tab:red', markersize=5, label='landing' if index == 0 else None)
            top.plot([target[0], landing[0]], [target[1], landing[1]], color='grey',
                     linewidth=0.8)
    xs = [row['target'][0] for row in rows]
    ys = [row['target'][1] for row in rows]
    if rows:
        top.set_xlim(min(xs) - 0.12, max(xs) + 0.12)
        top.set_ylim(min(ys) - 0.15, max(ys) + 0.15)
    top.set_aspect('equal')
    top.set_xlabel('x [m]')
    top.set_ylabel('y [m]')
    top.grid(True, alpha=0.3)
    top.legend(fontsize=8)
    errors = [1000.0 * (row['landing_error'] or 0.0) for row in rows]
    colours = ['tab:green' if row['hit'] else 'tab:red' for row in rows]
    bars.bar(range(len(rows)), errors, color=colours)
    bars.set_xticks(range(len(rows)))
    bars.set_xticklabels([f'({row["target"][0]:.2f}, {row["target"][1]:+.2f})' for row in rows],
                         rotation=60, fontsize=7)
    bars.set_ylabel('landing error [mm]')
    bars.grid(True, axis='y', alpha=0.3)
    episode_plots.save_figure(figure, path, dpi=100)

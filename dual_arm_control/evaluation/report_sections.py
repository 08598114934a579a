"""
The sections of docs/results.md: the headline table and one section per experiment.

Each section function takes the loaded results (report.load_results) and the link root of the
plots and returns its Markdown lines; a missing results file gives a 'Not run' note.
"""

from dual_arm_control.evaluation.experiment_metrics import reduction_percent
from dual_arm_control.evaluation.paper_results import PAPER_RESULTS
from dual_arm_control.evaluation.report_format import (failure_mode_sentence, image_links,
                                                       mean_std, MISSING, not_run, number,
                                                       paper, plot_links, statistics_table,
                                                       table, value_range)


def _at_speed(place_vs_toss, speed=1.0):
    """Return the place_vs_toss summary row at speed, or None."""
    if place_vs_toss is None:
        return None
    rows = [row for row in place_vs_toss['summary'] if abs(row['speed'] - speed) < 1e-9]
    return rows[0] if rows else None


def headline_rows(results):
    """Return the headline table rows: metric, ours, paper, paper source."""
    fast = results['fast_toss']
    metrics = fast['metrics'] if fast else {}
    workspace = results['toss_workspace']
    at_one = _at_speed(results['place_vs_toss'])
    robustness = results['robustness']
    targets = results['toss_to_target']
    rows = [
        ('impact speed, left / right arm (exp. 1)',
         f'{number(metrics.get("impact_speed_left"))} / '
         f'{number(metrics.get("impact_speed_right"), unit="m/s")}',
         paper('impact_speed'), PAPER_RESULTS['impact_speed']['source']),
        ('contact time gap between the pads (exp. 1)',
         number(metrics.get('contact_time_gap'), 1, 1000.0, 'ms'),
         'simultaneous (no number)', 'IV-A'),
        ('release position error (exp. 1)',
         number(metrics.get('release_position_error'), 1, 1000.0, 'mm'),
         f'within {paper("release_position_tolerance")} tolerance',
         PAPER_RESULTS['release_position_tolerance']['source']),
        ('release velocity error, relative (exp. 1)',
         number(metrics.get('release_velocity_error'), 1, 100.0, '%'), 'not reported', ''),
        ('cycle-time reduction at 1.0 m/s, toss vs place (exp. 3)',
         number(at_one and at_one['cycle_time_reduction_percent'], 1, unit='%'),
         paper('time_reduction_1ms', 0), PAPER_RESULTS['time_reduction_1ms']['source']),
        ('energy reduction at 1.0 m/s, toss vs place (exp. 3): signed ∫τᵀq̇dt as the paper '
         '(∫\\|τᵀq̇\\|dt; beyond gravity)',
         f'{number(at_one and at_one.get("signed_work_reduction_percent"), 1, unit="%")} '
         f'({number(at_one and at_one["energy_reduction_percent"], 1, unit="%")}; '
         f'{number(at_one and at_one["energy_without_gravity_reduction_percent"], 1, unit="%")})',
         paper('energy_reduction_1ms', 0), PAPER_RESULTS['energy_reduction_1ms']['source']),
        ('workspace extension by tossing (exp. 2): all landings (only tosses on target)',
         (f'{number(workspace["extension_percent"], 1, unit="%")} ('
          f'{number(workspace.get("extension_percent_on_target"), 1, unit="%")})'
          if workspace else MISSING),
         paper('workspace_extension', 0), PAPER_RESULTS['workspace_extension']['source']),
        ('success rate, robustness trials (exp. 4)',
         (f'{number(robustness["success_rate"], 1, 100.0, "%")} of {robustness["trials"]}'
          if robustness else MISSING), 'not reported', ''),
        ('landing error, toss to target: median / p95 over the grid (exp. 5)',
         (f'{number(targets["landing_error"].get("median"), 1, 1000.0)} / '
          f'{number(targets["landing_error"].get("p95"), 1, 1000.0, "mm")} '
          f'({len(targets["targets"])} targets, {len(targets.get("refused", []))} refused)'
          if targets else MISSING), 'within 0.2 x 0.4 m (no number)', ''),
    ]
    return rows


def fast_toss_section(results, link_root):
    """Experiment 1: paper_toss on the node graph."""
    fast = results['fast_toss']
    out = ['## 1. Fast grab-and-toss (paper IV-A, Figures 6-7)', '']
    if fast is None:
        return out + [not_run('fast_toss')]
    m = fast['metrics']
    out += [
        f'Runner: {fast["runner"]}, scenario `{fast["scenario"]}` (the 0.2 m, 0.7 kg cube from '
        f'the pallet, released at {fast["desired_release"]["position"]} m with '
        f'{[round(v, 3) for v in fast["desired_release"]["velocity"]]} m/s). The episode is '
        f'the product: every node in its own process, bridge in lockstep '
        f'(graph wall time {fast["graph_wall_time"]:.1f} s). Times count from the episode start '
        f'(0.3 s of sim time after the tare window). The in-process runner gives the same '
        f'events (largest difference over contact, release and cycle times and the release and '
        f'landing errors: {max(fast["inprocess_max_difference"].values(), default=0.0):.2g}).',
        '',
        table(('quantity', 'ours', 'paper'), [
            ('contact instant, left / right', f'{number(m["t_contact_left"])} / '
             f'{number(m["t_contact_right"], unit="s")}', f'~{paper("contact_time")}'),
            ('impact speed, left / right', f'{number(m["impact_speed_left"])} / '
             f'{number(m["impact_speed_right"], unit="m/s")}', paper('impact_speed')),
            ('impact speed along the contact normal, left / right',
             f'{number(m.get("impact_speed_along_normal_left"))} / '
             f'{number(m.get("impact_speed_along_normal_right"), unit="m/s")}', MISSING),
            ('contact time gap', number(m['contact_time_gap'], 1, 1000.0, 'ms'), MISSING),
            ('release instant', number(m['t_release'], unit='s'), MISSING),
            ('release position error', number(m['release_position_error'], 1, 1000.0, 'mm'),
             f'within {paper("release_position_tolerance")}'),
            ('release velocity error (relative)',
             number(m['release_velocity_error'], 1, 100.0, '%'), MISSING),
            ("landing error vs the desired release's ballistic landing",
             number(m['landing_error'], 1, 1000.0, 'mm'), MISSING),
            ('peak object speed while grasped', number(fast['peak_grasped_object_speed'],
                                                       unit='m/s'),
             f'{paper("toss_speed")} desired'),
            ('largest pad slip on the object', number(m['max_slip'], 1, 1000.0, 'mm'), MISSING),
            ('cycle time (start to both tools home)', number(m['cycle_time'], unit='s'),
             MISSING),
            ('energy left / right', f'{number(m["energy_left"], 1)} / '
             f'{number(m["energy_right"], 1, unit="J")}', MISSING),
            ('episode success (metrics.json criteria)', m['success'], MISSING)]),
        '', plot_links(results, 'fast_toss', link_root), '']
    return out


def workspace_section(results, link_root):
    """Experiment 2: tossing reachable space."""
    ws = results['toss_workspace']
    out = ['## 2. Tossing reachable space (paper Figure 8)', '']
    if ws is None:
        return out + [not_run('toss_workspace')]
    method = ws['method']
    speeds = [toss['speed'] for toss in ws['tosses']] or [0.0]
    grid = ws.get('target_grid', {'x': [], 'y': []})
    out += [
        f'Runner: {ws["runner"]}. {ws["toss_count"]} tosses of the paper cube, each planned by '
        f'the release planner for a landing target of the grid x {grid["x"]} x y {grid["y"]} m '
        f'on the front table (targets it refuses are left out) and for the '
        f'{len(grid.get("served_region_corners", []))} corners of the region it serves (the '
        f'convex hull of the points it serves on a {grid.get("corner_grid_step", 0):g} m grid '
        f'over the table): release point, direction and '
        f'speed ({min(speeds):.2f}-{max(speeds):.2f} m/s) chosen per target; '
        f'{ws["valid_count"]} were grasped, released and landed on the front table (their '
        f'measured landings are used), {ws["success_count"]} also met every episode '
        f'criterion.',
        '',
        'Method. Joint reachable space: for each arm '
        f'{method["samples_per_arm"]} joint configurations sampled uniformly within the limits '
        f'(seed {method["seed"]}); A1 (vertical) is turned so the pad normal points across '
        f'the cell (left -y, right +y), keeping samples with A1 in its limits and the normal '
        f'within {method["pad_max_tilt_deg"]:g} deg of horizontal ({method["kept_samples"]} '
        f'kept). An object centre c is jointly reachable when left tool samples fall in the '
        f'grid cell of c + (0, {method["half_width"]:g}, 0) and right tool samples in that of '
        f'c - (0, {method["half_width"]:g}, 0) within the same {method["slab_height"]:g} m '
        f'height slab, for tool heights {method["z_band"]} m (from the object resting on the '
        f'front table up to above the standby height); top view on a '
        f'{method["grid"]["cell"]:g} m grid over x >= {method["grid"]["x0"]:g} m (in front '
        f'of the bases). Collisions and self-collisions are not modelled, so the joint space is '
        f'if anything too large (the extension too small). Tossing space: the convex hull of '
        f'the landings on the same grid. Extension = hull cells outside the joint space / '
        f'joint space.',
        '',
        f'Reach of the toss: the farthest landing is '
        f'{number(ws["farthest_landing"], 3, unit="m")} from the nominal release point '
        f'horizontally; a drag-free toss at {ws["fastest_toss"]:.2f} m/s released at that '
        f'height lands at most {number(ws["longest_toss"], 3, unit="m")} away, while the joint '
        f'reachable space already reaches x = {number(ws["joint_max_x_at_y0"], 3, unit="m")} '
        f'at y = 0. The planner caps the release speed (release_planning.max_release_speed).',
        '',
        table(('quantity', 'ours', 'paper'), [
            ('tosses (valid landings)', f'{ws["toss_count"]} ({ws["valid_count"]})',
             paper('tosses')),
            ('joint reachable area (top view)', number(ws['joint_area'], 3, unit='m²'),
             MISSING),
            ('landing hull area', number(ws['toss_area'], 3, unit='m²'), MISSING),
            ('added area outside the joint space', number(ws['added_area'], 3, unit='m²'),
             MISSING),
            ('landing x range / y range', f'{value_range(ws["landing_extent"]["x"])} / '
             f'{value_range(ws["landing_extent"]["y"])} m', MISSING),
            ('extension', number(ws['extension_percent'], 1, unit='%'),
             paper('workspace_extension', 0)),
            ('extension by the tosses that met every criterion (landed within 5 cm of their '
             'target)', number(ws.get('extension_percent_on_target'), 1, unit='%'), MISSING)]),
        '', plot_links(results, 'toss_workspace', link_root), '']
    return out


def place_vs_toss_section(results, link_root):
    """Experiment 3: pick-and-place vs pick-and-toss."""
    pvt = results['place_vs_toss']
    out = ['## 3. Pick-and-place vs pick-and-toss (paper IV-B, Figures 9-10)', '']
    if pvt is None:
        return out + [not_run('place_vs_toss')]
    settings = pvt['settings']
    rows = []
    for row in pvt['summary']:
        place, toss = row['pick_and_place'], row['pick_and_toss']
        rows.append((
            f'{row["speed"]:.1f}', mean_std(place['cycle_time']), mean_std(toss['cycle_time']),
            number(row['cycle_time_reduction_percent'], 1, unit='%'),
            mean_std(place.get('signed_work'), 1), mean_std(toss.get('signed_work'), 1),
            number(row.get('signed_work_reduction_percent'), 1, unit='%'),
            number(row['energy_reduction_percent'], 1, unit='%'),
            number(row['positive_work_reduction_percent'], 1, unit='%'),
            number(row['energy_without_gravity_reduction_percent'], 1, unit='%'),
            f'{place["successes"]}/{place["runs"]}', f'{toss["successes"]}/{toss["runs"]}',
            mean_std(place['max_slip'], 1, 1000.0)))
    probe = pvt['equal_impact_probe']
    out += [
        f'Runner: {pvt["runner"]}. At each task speed v, pick-and-toss is `'
        f'{settings["toss_scenario"]}` with reach speed v and release velocity v along its '
        f'direction (released at {settings["toss_release_position"]} m); pick-and-place is `'
        f'{settings["place_scenario"]}` (place at '
        f'{[round(x, 3) for x in settings["place_target"]]} m on the front table) with reach '
        f'and carrying speed v, grabbing at {settings["place_impact_speed"]:g} m/s as the '
        f"paper's near-zero-speed baseline (slowing from v to it between "
        f'{settings["place_slowdown"][1]:g} and {settings["place_slowdown"][0]:g} m from '
        f"the faces); the toss grabs at {settings['impact_speed']:g} m/s. "
        f'{pvt["repeats"]} runs per task and speed (sensor-noise seeds); mean ± std.',
        '',
        'Definitions (episode_metrics, identical for both tasks): cycle time = from the '
        'episode start to the first instant after the release (both pads off the object for '
        '20 ms: the toss release, or the pads leaving the placed object) when both tools are '
        'back within 3 cm of their start positions. Energy, both arms summed, over that cycle: '
        "the signed mechanical work ∫τᵀq̇dt (the paper's measure: power the drives return "
        'counts against what they spend), ∫|τᵀq̇|dt (nothing returned), the positive work '
        '∫max(τᵀq̇, 0)dt and the energy beyond gravity ∫|(τ - g(q))ᵀq̇|dt. Most of ∫|τᵀq̇|dt '
        'is the '
        "arms' own weight going down to the pallet and back up to standby, the same in both "
        'tasks; the last column leaves it out. Success: the episode criteria of '
        'metrics.json (for place: placed within 3 cm, released below 0.1 m/s; pad slip is '
        'not a criterion for place, so it is listed).',
        '',
        table(('v [m/s]', 'place cycle [s]', 'toss cycle [s]', 'time reduction',
               'place ∫τᵀq̇dt [J]', 'toss ∫τᵀq̇dt [J]', 'signed-work reduction',
               '∫|τᵀq̇|dt reduction',
               'positive-work reduction', 'reduction beyond gravity', 'place ok', 'toss ok',
               'place slip [mm]'), rows),
        '',
        f'Paper at 1.0 m/s: time {paper("time_reduction_1ms", 0)} shorter, energy '
        f'{paper("energy_reduction_1ms", 0)} less, with the place contacting at '
        f'{paper("place_contact_speed")} and releasing at {paper("place_release_speed")} (its '
        f'toss impacts at {paper("toss_impact_speed_1ms")}).',
        '',
        f'Equal-impact run: one pick-and-place at v = {probe["speed"]:.1f} m/s grabbing at the '
        f"toss's impact speed {probe['impact_speed_setting']:g} m/s: success "
        f'{probe["success"]}, '
        f'cycle time {number(probe["cycle_time"], unit="s")}, slip '
        f'{number(probe["max_slip"], 1, 1000.0, "mm")}, place error '
        f'{number(probe["place_position_error"], 1, 1000.0, "mm")}, signed work '
        f'{number(probe.get("signed_work"), 1, unit="J")}. Against it the toss at the same '
        f'speed is {number(_probe_reduction(pvt, "cycle_time"), 1, unit="%")} shorter and '
        f'needs {number(_probe_reduction(pvt, "signed_work"), 1, unit="%")} less signed work: '
        f'what tossing alone gains once both grab with impact. A missing cycle time means the '
        f'arms were not back home within the {settings["place_duration"]:g} s run.',
        '', plot_links(results, 'place_vs_toss', link_root), '']
    return out


def _probe_reduction(pvt, key):
    """Return how much less key the toss needs than the equal-impact place run [%]."""
    probe = pvt['equal_impact_probe']
    toss = _at_speed(pvt, probe['speed'])
    if toss is None or key not in toss['pick_and_toss']:
        return None
    return reduction_percent(probe.get(key), toss['pick_and_toss'][key]['mean'])


def robustness_section(results, link_root):
    """Experiment 4 (dual_arm_eval): success rate and metric distribution."""
    summary = results['robustness']
    out = ['## 4. Robustness (dual_arm_eval)', '']
    if summary is None:
        return out + ['_Not run: `robustness/summary.json` is missing. Run `dual_arm_eval` '
                      '(see README)._', '']
    rows = [(key, *(number(entry.get(stat), 4) for stat in
                    ('mean', 'median', 'p95', 'min', 'max')), entry.get('count', MISSING))
            for key, entry in sorted(summary.get('metrics', {}).items())]
    failures = summary.get('failures', [])
    out += [
        f'Scenario `{summary.get("scenario")}`, runner {summary.get("runner")}, '
        f'{summary.get("trials")} trials ({summary.get("jobs")} jobs, seed '
        f'{summary.get("seed")}): success rate '
        f'{number(summary.get("success_rate"), 1, 100.0, "%")}, wall time '
        f'{number(summary.get("wall_time"), 0, unit="s")} '
        f'({number(summary.get("trials_per_hour"), 0)} trials/h).', '',
        table(('metric', 'mean', 'median', 'p95', 'min', 'max', 'count'), rows), '',
        f'Failures: {len(failures)}' + ('' if not failures else ': ' + '; '.join(
            f'trial {item.get("trial")}: {item.get("reason")}' for item in failures[:10])
            + (' …' if len(failures) > 10 else '')), '']
    out += image_links([plot for plot in results.get('robustness_plots', [])
                        if not plot.startswith('robustness/displaced')], link_root)
    out += ['']
    displaced = results['displaced']
    if displaced is not None:
        out += ['Mid-reach displacement run (`robustness/displaced/metrics.json`): success '
                f'{displaced.get("success")}, contact gap '
                f'{number(displaced.get("contact_time_gap"), 1, 1000.0, "ms")}, release '
                'position error '
                f'{number(displaced.get("release_position_error"), 1, 1000.0, "mm")}, '
                f'landing error {number(displaced.get("landing_error"), 1, 1000.0, "mm")}.',
                '']
        out += image_links([plot for plot in results.get('robustness_plots', [])
                            if plot.startswith('robustness/displaced')], link_root)
        out += ['']
    return out


# More dual_arm_eval batches: the whole object catalogue (config/scenarios/catalogue_random*.yaml),
# a box turned while carried (paper_toss_oriented_random.yaml) and landing targets drawn over the
# front table (toss_to_target_random.yaml).
CATALOGUE_FOLDERS = ('robustness_catalogue', 'robustness_catalogue_place', 'robustness_oriented',
                     'robustness_targets')
CATALOGUE_METRICS = ('contact_time_gap', 'max_slip', 'impact_speed_left', 'impact_speed_right',
                     'arm_collision_count', 'release_position_error', 'release_orientation_error',
                     'landing_error', 'place_position_error', 'box_tilt_at_place')


def catalogue_section(results, link_root):
    """Experiment 4b (dual_arm_eval): catalogue boxes at random poses; a turned box; targets."""
    out = ['## 4b. Robustness over the object catalogue, a turned box and random landing targets '
           '(dual_arm_eval)', '']
    for folder in CATALOGUE_FOLDERS:
        summary, plots = results.get('catalogue', {}).get(folder, (None, []))
        if summary is None:
            out += [f'_Not run: `{folder}/summary.json` is missing._', '']
            continue
        out += [f'### `{summary.get("scenario")}`', '',
                f'{summary.get("trials")} trials, runner {summary.get("runner")}, seed '
                f'{summary.get("seed")}: success rate '
                f'{number(summary.get("success_rate"), 1, 100.0, "%")}.', '',
                statistics_table(summary.get('metrics', {}), CATALOGUE_METRICS,
                                 ('median', 'p95', 'max')), '',
                failure_mode_sentence(summary.get('failures', [])), '']
        out += image_links(plots, link_root) + ['']
    return out


def toss_to_target_section(results, link_root):
    """Experiment 5: landing error over a grid of targets."""
    ttt = results['toss_to_target']
    out = ['## 5. Toss to target', '']
    if ttt is None:
        return out + [not_run('toss_to_target')]
    rows = [(f'({row["target"][0]:.2f}, {row["target"][1]:+.2f})',
             str([round(x, 2) for x in row.get('release_position_planned', [])]),
             number(row['release_speed_planned'], 2), number(row['release_elevation_deg'], 1),
             number(row['landing_error'], 1, 1000.0),
             number(row.get('release_speed_error'), 1, 100.0),
             number(row.get('release_direction_error'), 1),
             number(row['max_slip'], 1, 1000.0), number(row.get('max_joint_speed_ratio'), 1),
             'yes' if row['hit'] else 'no')
            for row in ttt['targets']]
    errors, bias = ttt['landing_error'], ttt.get('landing_bias') or [None, None]
    refused = ttt.get('refused', [])
    out += [
        f'Runner: {ttt["runner"]}. Task `toss_to_target` (paper_toss otherwise) over a grid of '
        f'{len(ttt["targets"]) + len(refused)} targets on the front table (x {ttt["grid"]["x"]},'
        f' y {ttt["grid"]["y"]} m): for each, the release planner (core/toss_planning.py) '
        f'chooses the release point, direction and speed (at most '
        f'{ttt["max_release_speed"]:g} m/s); a target it cannot serve is refused with its '
        f'reason, not attempted. Landing error = horizontal distance between the measured '
        f'landing of the box centre and the target; a hit is within '
        f'{number(ttt["landing_limit"], 0, 1000.0, "mm")}.',
        '',
        f'Landing error over {errors["count"]} attempted targets: median '
        f'{number(errors.get("median"), 1, 1000.0)} mm, p95 {number(errors.get("p95"), 1, 1000.0)}'
        f' mm, max {number(errors["max"], 1, 1000.0)} mm; {ttt["hit_count"]}/'
        f'{len(ttt["targets"])} hits, {errors["missing"]} without a landing; mean signed offset '
        f'(landing - target) x {number(bias[0], 1, 1000.0)} mm, y {number(bias[1], 1, 1000.0)} mm.'
        f' Ballistic prediction from the measured release state vs measured landing: mean '
        f'{number(ttt["landing_prediction_error"]["mean"], 1, 1000.0, "mm")}. Success (all '
        f'episode criteria, pad slip <= 10 mm included): {ttt["success_count"]}/'
        f'{len(ttt["targets"])}. The twin does not enforce the iiwa\'s joint speed limits; '
        f'the column before last is the largest |qdot| / limit of either arm in the episode '
        f'(the KUKA controller stops an arm above 1).',
        '',
        table(('target (x, y) [m]', 'release point [m]', 'release speed [m/s]',
               'elevation [deg]', 'landing error [mm]', 'release speed error [%]',
               'release direction error [deg]', 'slip [mm]', 'worst joint speed / limit',
               'hit'), rows),
        '',
        *(f'Refused: ({item["target"][0]:.2f}, {item["target"][1]:+.2f}): {item["reason"]}'
          for item in refused), '',
        '', plot_links(results, 'toss_to_target', link_root), '']
    return out

"""The paper's experiments and numbers, what both the experiments and the report read."""

EXPERIMENTS = ('fast_toss', 'toss_workspace', 'place_vs_toss', 'toss_to_target',
               'catalogue_grasps')
RESULTS_FILE = 'results.json'

# The paper's numbers (Bombile & Billard 2022, section IV), one place for the report.
PAPER_RESULTS = {
    'impact_speed': {'value': 0.5, 'unit': 'm/s', 'source': 'IV-A, Figure 6: "impact the '
                     'object around t=1.05s with a speed of 0.5 m/s"'},
    'contact_time': {'value': 1.05, 'unit': 's', 'source': 'IV-A, Figure 6'},
    'release_position_tolerance': {'value': 0.03, 'unit': 'm', 'source': 'IV-A, Figure 7a: '
                                   '"reaches the desired release location within a tolerance '
                                   'of 0.03m"'},
    'toss_speed': {'value': 0.8, 'unit': 'm/s', 'source': 'IV-A, Figure 6 caption'},
    'tosses': {'value': 50, 'unit': '', 'source': 'IV-A, Figure 8'},
    'workspace_extension': {'value': 20.0, 'unit': '%', 'qualifier': '>=', 'source': 'IV-A, '
                            'Figure 8: "extends the dual-arm system reachable workspace by at '
                            'least 20%"'},
    'time_reduction_1ms': {'value': 19.0, 'unit': '%', 'source': 'IV-B: "around 19% shorter" '
                           'at 1.0 m/s'},
    'energy_reduction_1ms': {'value': 24.0, 'unit': '%', 'source': 'IV-B, Figure 9b: "consumed '
                             '24% less" at 1.0 m/s'},
    'place_contact_speed': {'value': 0.11, 'unit': 'm/s', 'source': 'IV-B, Figure 9a'},
    'place_release_speed': {'value': 0.13, 'unit': 'm/s', 'source': 'IV-B, Figure 9a'},
    'toss_impact_speed_1ms': {'value': 0.40, 'unit': 'm/s', 'source': 'IV-B, Figure 9a'},
    'repetitions': {'value': 5, 'unit': '', 'source': 'IV-B, Figure 9 caption'},
}

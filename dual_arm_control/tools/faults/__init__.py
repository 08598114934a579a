"""The fault campaign dual_arm_faults: fault kinds, graph runs with a probe, outcomes, report."""

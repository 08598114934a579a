"""Write a Scenario back as the mapping dual_arm_control.scenario.load_scenario reads."""

from dataclasses import fields

from dual_arm_control.core.arms import ARMS
from dual_arm_control.randomization import randomization_document
from dual_arm_control.scenario import Speeds
from dual_arm_control.scenario_reader import settings_document
from dual_arm_control.sensor_models import MocapConfig


def scenario_document(scenario):
    """
    Return scenario as the mapping load_scenario reads (write it with yaml.safe_dump).

    Every value is explicit (object size, mass and friction beside its type, 3D positions,
    both arms' initial configuration, every sensor field), so loading the document gives back
    an equal Scenario whatever the catalogue's and the loader's defaults.
    """
    def numbers(values):
        return [float(value) for value in values]

    box = scenario.object
    object_entry = {} if box.type is None else {'type': box.type}
    object_entry.update(size=numbers(box.size), mass=float(box.mass),
                        friction=float(box.friction), position=numbers(box.position),
                        yaw=float(box.yaw))
    document = {'name': scenario.name, 'seed': int(scenario.seed), 'task': scenario.task,
                'object': object_entry}
    if scenario.release is not None:
        document['release'] = {'position': numbers(scenario.release.position),
                               'velocity': numbers(scenario.release.velocity)}
    if scenario.landing_target is not None:
        document['landing_target'] = numbers(scenario.landing_target)
    if scenario.release_orientation is not None:
        document['release_orientation'] = numbers(scenario.release_orientation)
    if scenario.place is not None:
        document['place'] = {'position': numbers(scenario.place)}
    document['speeds'] = {item.name: float(getattr(scenario.speeds, item.name))
                          for item in fields(Speeds)
                          if getattr(scenario.speeds, item.name) is not None}
    if scenario.perturbations:
        document['perturbations'] = [
            {'time': float(item.time), 'object_displacement': numbers(item.object_displacement)}
            for item in scenario.perturbations]
    document['duration'] = float(scenario.duration)
    document['initial_configuration'] = {arm: numbers(scenario.initial_configuration[arm])
                                         for arm in ARMS}
    mocap, ft = scenario.sensors.mocap, scenario.sensors.ft
    document['sensors'] = {
        'mocap': {item.name: float(getattr(mocap, item.name)) for item in fields(MocapConfig)},
        'ft': {'force_noise': float(ft.force_noise), 'torque_noise': float(ft.torque_noise),
               'force_bias': numbers(ft.force_bias), 'torque_bias': numbers(ft.torque_bias)}}
    if scenario.conveyor is not None:
        document['conveyor'] = settings_document(scenario.conveyor)
    if scenario.incoming_belt is not None:
        document['incoming_belt'] = settings_document(scenario.incoming_belt)
    if scenario.randomization is not None:
        document['randomization'] = randomization_document(scenario.randomization)
    return document

"""
bag_play: publish the topics of an MCAP bag again, with their recorded timing or in lockstep.

Timed (default): each message goes out at its recorded log time after the start, scaled by
--rate; the bag's /clock (recorded from the sim bridge) is republished with the rest, so nodes
with use_sim_time follow the recorded sim time. With --clock [HZ] bag_play publishes /clock
itself instead, HZ times per wall second, from the bag's log time (as rosbag2's --clock does):
for bags without a /clock, or whose log time is the time to follow. Lockstep (--lockstep): the
messages go out in recorded order as fast as the node under test allows. Each --wait-for topic
is an output of that node recorded in the bag (header-stamped, not published); its recorded
stamps are the input stamps the node answers. Messages are grouped by stamp (header stamp,
/clock's time): where a group stamped t ends and the node answered t in the recording, bag_play
first sends the messages stamped t among the next few recorded ones (the recorder may log one
of a cycle's inputs late), then waits until the node has published a message stamped t on every
--wait-for topic (or --wait-timeout passed: counted and reported). Messages are published as
recorded (serialized CDR), never deserialized, each topic with the QoS its publishers offered
when recorded (reliable, volatile, keep-last 100 if unknown). Input: an .mcap file (with its
split files <stem>_N.mcap) or a rosbag2 folder.

This module is the command line; bags/playback.py checks the options against the bag and
nodes/bag_player.py is the node that publishes and waits.
"""

import argparse
import sys
import time

from dual_arm_control.bags import BagError
from dual_arm_control.bags.playback import Playback
from dual_arm_control.bags.reader import BagReader
from dual_arm_control.nodes.bag_player import BagPlayer, PlaybackStats
from dual_arm_control.nodes.process import StopRequest
import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.signals import SignalHandlerOptions

# /clock messages per wall second of `--clock` without a value (rosbag2's default).
DEFAULT_CLOCK_RATE = 40.0

EXAMPLES = """\
examples:
  # replay a recorded run at its recorded pace (/clock included)
  bag_play runs/latest/bag.mcap
  # /clock from the bag's log time at 100 Hz, instead of the recorded /clock
  bag_play bag.mcap --clock 100
  # twice as fast, only the arm states, from 0.5 s into the bag for 1 s
  bag_play bag.mcap --rate 2 --regex 'joint_states$' --start-offset 0.5 --duration 1
  # everything but ground truth, the left arm's state under another name, 3 passes
  bag_play bag.mcap --exclude '^/.*ground_truth' --remap /left/joint_states:=/test/js \\
      --loops 3
  # exact reproduction: feed the motion generator's recorded inputs to a fresh
  # ds_motion_generator (same parameters as the recorded run, lockstep:=true) tick by
  # tick; the phase is latched, so the bag has all of it even if the recorder started late
  bag_play bag.mcap --lockstep --topics /clock /object/state /left/joint_states \\
      /right/joint_states /left/ft_wrench /right/ft_wrench --wait-for /dual_arm/phase

exit codes: 0 played; 1 a lockstep wait timed out or the node under test went away;
2 bad input (file, damaged bag without --recover, unknown topic, bad option value).
"""


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are BagErrors (one line, exit 2), not usage dumps."""

    def error(self, message):
        """Raise BagError with argparse's message instead of printing usage and exiting."""
        raise BagError(message)


def parse_arguments(argv):
    """Parse bag_play's own arguments (see split_arguments); raise BagError if invalid."""
    parser = _Parser(prog='bag_play', description=__doc__.split('\n')[1],
                     epilog=EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('bag', help='.mcap file (split files <stem>_N.mcap follow) or rosbag2 '
                        'folder with metadata.yaml')
    parser.add_argument('--topics', nargs='+', default=[], metavar='TOPIC',
                        help='play these topics (default: all, or those matching --regex)')
    parser.add_argument('-e', '--regex', help='play the topics matching this expression')
    parser.add_argument('-x', '--exclude', metavar='REGEX',
                        help='do not play the topics matching this expression')
    parser.add_argument('--remap', action='append', default=[], metavar='/OLD:=/NEW',
                        help='publish bag topic /OLD as /NEW (repeatable)')
    parser.add_argument('-r', '--rate', type=float, default=1.0,
                        help='timed mode: playback speed factor (2 = twice as fast)')
    parser.add_argument('--clock', type=float, nargs='?', const=DEFAULT_CLOCK_RATE,
                        metavar='HZ',
                        help="timed mode: publish /clock from the bag's log time HZ times per "
                             f'wall second (default {DEFAULT_CLOCK_RATE:g} without a value) for '
                             "nodes with use_sim_time; the bag's own /clock is not played")
    parser.add_argument('--start-offset', type=float, default=0.0, metavar='SECONDS',
                        help='start this far after the first message of the bag [s]')
    parser.add_argument('--duration', type=float, metavar='SECONDS',
                        help='play this much of the bag (log time) per pass [s]')
    parser.add_argument('-l', '--loop', action='store_true',
                        help='play the window again and again until interrupted')
    parser.add_argument('--loops', type=int, metavar='N',
                        help='play the window N times (implies --loop)')
    parser.add_argument('--lockstep', action='store_true',
                        help='recorded order, as fast as the node under test allows')
    parser.add_argument('--wait-for', action='append', default=[], metavar='TOPIC',
                        help='lockstep: header-stamped output topic of the node under test, '
                             'recorded in the bag: after the inputs stamped t, wait for its '
                             'answer stamped t if it answered t in the recording (repeatable)')
    parser.add_argument('--wait-timeout', type=float, default=10.0, metavar='SECONDS',
                        help='lockstep: wall time to wait at one barrier [s]')
    parser.add_argument('--wait-for-subscribers', action='store_true',
                        help='first wait until every topic has a subscriber (always in '
                             'lockstep)')
    parser.add_argument('--startup-timeout', type=float, default=30.0, metavar='SECONDS',
                        help='wall time to wait for subscribers and --wait-for publishers [s]')
    parser.add_argument('--settle', type=float, default=1.0, metavar='SECONDS',
                        help='wall time between matching and the first message, so both '
                             'sides of every match know each other [s]')
    parser.add_argument('--recover', action='store_true',
                        help='play the recoverable messages of a torn, truncated or corrupt '
                             'bag (refused without this flag)')
    options = parser.parse_args(argv)
    for name in ('rate', 'wait_timeout', 'startup_timeout'):
        if not getattr(options, name) > 0.0:
            raise BagError(f'--{name.replace("_", "-")} must be > 0, got '
                           f'{getattr(options, name)}')
    if options.settle < 0.0:
        raise BagError(f'--settle must be >= 0, got {options.settle}')
    if options.loops is not None and options.loops < 1:
        raise BagError(f'--loops must be >= 1, got {options.loops}')
    if options.wait_for and not options.lockstep:
        raise BagError('--wait-for needs --lockstep')
    if options.clock is not None and not options.clock > 0.0:
        raise BagError(f'--clock must be > 0 Hz, got {options.clock}')
    if options.clock is not None and options.lockstep:
        raise BagError("--clock needs timed playback; in lockstep play the bag's own /clock "
                       '(--topics /clock ...)')
    return options


def split_arguments(argv):
    """
    Return (bag_play's arguments, the ROS arguments) of a command line (argv[0] excluded).

    The ROS arguments are those between `--ros-args` and `--` (or the end). rclpy's own
    remove_ros_args is not used: it takes '/old:=/new' for a deprecated ROS remap rule even
    after --remap.
    """
    own, ros, in_ros = [], [], False
    for argument in argv[1:]:
        if argument == '--ros-args':
            in_ros = True
            ros.append(argument)
        elif in_ros and argument == '--':
            in_ros = False
        else:
            (ros if in_ros else own).append(argument)
    return own, ros


def main(argv=None):
    """Play a bag; return the exit code (0 played, 1 lockstep trouble, 2 bad input)."""
    argv = sys.argv if argv is None else argv
    own_arguments, ros_arguments = split_arguments(argv)
    try:
        options = parse_arguments(own_arguments)
        reader = BagReader(options.bag, recover=options.recover)
        playback = Playback(reader, options)
    except SystemExit as exit_request:
        return exit_request.code
    except BagError as error:
        print(f'bag_play: {error}', file=sys.stderr)
        return 2
    for summary in reader.damaged:
        print(f'bag_play: warning: {summary.path} is {summary.status} ({summary.problem}); '
              f'playing its {summary.message_count} recoverable messages', file=sys.stderr)
    # SIGINT/SIGTERM only set a flag, so playback stops between two messages (and still prints
    # its summary) instead of rclpy shutting the context down under a publish call.
    rclpy.init(args=argv[:1] + ros_arguments, signal_handler_options=SignalHandlerOptions.NO)
    player = None
    stop = StopRequest()
    try:
        player = BagPlayer(reader, playback, options, stop)
        if options.lockstep or options.wait_for_subscribers:
            unmatched = player.wait_for_graph() if player.running() else []
            missing = [name for name in unmatched if name in playback.wait_names.values()]
            if missing and player.running():
                print(f'bag_play: no publisher on {missing} after {options.startup_timeout:g} '
                      's: is the node under test running?', file=sys.stderr)
                return 1
            if unmatched and player.running():
                print(f'bag_play: warning: no subscriber on {unmatched}; playing anyway',
                      file=sys.stderr)
        stats = player.play()
    except (KeyboardInterrupt, ExternalShutdownException):
        stats = player.stats if player is not None else PlaybackStats()
        stats.interrupted = True
        stats.finished = time.monotonic()
    except BagError as error:
        print(f'bag_play: {error}', file=sys.stderr)
        return 2
    finally:
        stop.restore()
        if player is not None:
            player.close()
        rclpy.try_shutdown()
    print(stats.line(), flush=True)
    return 1 if stats.timeouts or stats.node_lost else 0


if __name__ == '__main__':
    sys.exit(main())

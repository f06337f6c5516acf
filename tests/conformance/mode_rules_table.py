"""What ArduPilot SITL did in every mode sweep of test_mode_rules.py.

Printed by ``python modesweep.py KIND sitl`` (tests/conformance) on the SITL build in
../shared/ardupilot-sitl (ArduPilot 4.7.0-dev, 90700977, 2025-07-21), booted at the
conformance missions' origin with SITL's default parameters. Each entry: mode -> Step
(COMMAND_ACK result, mode and armed state after, ``severity:text`` of the texts caused).
"""

from __future__ import annotations

from modesweep import Step

TABLE: dict[str, dict[str, dict[str, Step]]] = {
    "rover": {
        "set_before_ready": {
            "RTL": Step(4, "MANUAL", False, ("4:Flight mode change failed",)),
            "SMART_RTL": Step(4, "MANUAL", False, ("4:Flight mode change failed",)),
            "MANUAL": Step(0, "MANUAL", False, ()),
            "ACRO": Step(0, "ACRO", False, ()),
            "STEERING": Step(0, "STEERING", False, ()),
            "HOLD": Step(0, "HOLD", False, ()),
            "LOITER": Step(4, "MANUAL", False, ("4:Flight mode change failed",)),
            "FOLLOW": Step(4, "MANUAL", False, ("4:Flight mode change failed",)),
            "SIMPLE": Step(0, "SIMPLE", False, ()),
            "DOCK": Step(
                4, "MANUAL", False, ("5:Dock: target not acquired", "4:Flight mode change failed")
            ),
            "CIRCLE": Step(4, "MANUAL", False, ("4:Flight mode change failed",)),
            "AUTO": Step(
                4, "MANUAL", False, ("5:No Mission. Can't set AUTO.", "4:Flight mode change failed")
            ),
            "GUIDED": Step(0, "GUIDED", False, ()),
            "INITIALISING": Step(4, "MANUAL", False, ("4:Flight mode change failed",)),
        },
        "set_armed_before_ready": {
            "RTL": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "SMART_RTL": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "MANUAL": Step(0, "MANUAL", True, ()),
            "ACRO": Step(0, "ACRO", True, ()),
            "STEERING": Step(0, "STEERING", True, ()),
            "HOLD": Step(0, "HOLD", True, ()),
            "LOITER": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "FOLLOW": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "SIMPLE": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "DOCK": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "CIRCLE": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "AUTO": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "GUIDED": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "INITIALISING": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
        },
        "set_ready": {
            "MANUAL": Step(0, "MANUAL", False, ()),
            "ACRO": Step(0, "ACRO", False, ()),
            "STEERING": Step(0, "STEERING", False, ()),
            "HOLD": Step(0, "HOLD", False, ()),
            "LOITER": Step(0, "LOITER", False, ()),
            "FOLLOW": Step(4, "MANUAL", False, ("4:Flight mode change failed",)),
            "SIMPLE": Step(0, "SIMPLE", False, ()),
            "DOCK": Step(
                4, "MANUAL", False, ("5:Dock: target not acquired", "4:Flight mode change failed")
            ),
            "CIRCLE": Step(0, "CIRCLE", False, ()),
            "AUTO": Step(
                4, "MANUAL", False, ("5:No Mission. Can't set AUTO.", "4:Flight mode change failed")
            ),
            "RTL": Step(0, "RTL", False, ()),
            "SMART_RTL": Step(0, "SMART_RTL", False, ()),
            "GUIDED": Step(0, "GUIDED", False, ()),
            "INITIALISING": Step(4, "MANUAL", False, ("4:Flight mode change failed",)),
        },
        "arm_ready": {
            "MANUAL": Step(0, "MANUAL", True, ("6:Throttle armed",)),
            "ACRO": Step(0, "ACRO", True, ("6:Throttle armed",)),
            "STEERING": Step(0, "STEERING", True, ("6:Throttle armed",)),
            "HOLD": Step(0, "HOLD", True, ("6:Throttle armed",)),
            "LOITER": Step(0, "LOITER", True, ("6:Throttle armed",)),
            "SIMPLE": Step(0, "SIMPLE", True, ("6:Throttle armed",)),
            "CIRCLE": Step(0, "CIRCLE", True, ("6:Throttle armed",)),
            "RTL": Step(4, "RTL", False, ("2:Arm: Mode not armable",)),
            "SMART_RTL": Step(4, "SMART_RTL", False, ("2:Arm: Mode not armable",)),
            "GUIDED": Step(0, "GUIDED", True, ("6:Throttle armed",)),
        },
        "set_armed_ready": {
            "MANUAL": Step(0, "MANUAL", True, ()),
            "ACRO": Step(0, "ACRO", True, ()),
            "STEERING": Step(0, "STEERING", True, ()),
            "HOLD": Step(0, "HOLD", True, ()),
            "LOITER": Step(0, "LOITER", True, ()),
            "FOLLOW": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "SIMPLE": Step(0, "SIMPLE", True, ()),
            "DOCK": Step(
                4, "MANUAL", True, ("5:Dock: target not acquired", "4:Flight mode change failed")
            ),
            "CIRCLE": Step(0, "CIRCLE", True, ()),
            "AUTO": Step(
                4, "MANUAL", True, ("5:No Mission. Can't set AUTO.", "4:Flight mode change failed")
            ),
            "RTL": Step(0, "RTL", True, ()),
            "SMART_RTL": Step(0, "SMART_RTL", True, ()),
            "GUIDED": Step(0, "GUIDED", True, ()),
            "INITIALISING": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
        },
    },
    "copter": {
        "set_before_ready": {
            "RTL": Step(0, "RTL", False, ()),
            "SMART_RTL": Step(
                4, "STABILIZE", False, ("4:Mode change to SMARTRTL failed: init failed",)
            ),
            "STABILIZE": Step(0, "STABILIZE", False, ()),
            "ACRO": Step(0, "ACRO", False, ()),
            "ALT_HOLD": Step(0, "ALT_HOLD", False, ()),
            "AUTO": Step(0, "AUTO", False, ()),
            "GUIDED": Step(0, "GUIDED", False, ()),
            "LOITER": Step(0, "LOITER", False, ()),
            "CIRCLE": Step(0, "CIRCLE", False, ()),
            "LAND": Step(0, "LAND", False, ()),
            "DRIFT": Step(0, "DRIFT", False, ()),
            "SPORT": Step(4, "STABILIZE", False, ("4:No such mode 13",)),
            "FLIP": Step(4, "STABILIZE", False, ("4:Mode change to FLIP failed: init failed",)),
            "AUTOTUNE": Step(
                4, "STABILIZE", False, ("4:Mode change to AUTOTUNE failed: init failed",)
            ),
            "POSHOLD": Step(0, "POSHOLD", False, ()),
            "BRAKE": Step(0, "BRAKE", False, ()),
            "THROW": Step(0, "THROW", False, ()),
            "AVOID_ADSB": Step(0, "AVOID_ADSB", False, ()),
            "GUIDED_NOGPS": Step(0, "GUIDED_NOGPS", False, ()),
            "FLOWHOLD": Step(
                4, "STABILIZE", False, ("4:Mode change to FLOWHOLD failed: init failed",)
            ),
            "FOLLOW": Step(
                4,
                "STABILIZE",
                False,
                ("4:Set FOLL_ENABLE = 1", "4:Mode change to FOLLOW failed: init failed"),
            ),
            "ZIGZAG": Step(0, "ZIGZAG", False, ()),
            "SYSTEMID": Step(
                4,
                "STABILIZE",
                False,
                (
                    "4:No axis selected, SID_AXIS = 0",
                    "4:Mode change to SYSTEMID failed: init failed",
                ),
            ),
            "AUTOROTATE": Step(4, "STABILIZE", False, ("4:No such mode 26",)),
            "AUTO_RTL": Step(
                4,
                "STABILIZE",
                False,
                (
                    "4:Unable to start landing sequence",
                    "4:Mode change to AUTO RTL failed: No return path or landing sequence found",
                ),
            ),
            "TURTLE": Step(4, "STABILIZE", False, ("4:Mode change to TURTLE failed: init failed",)),
            "RATE_ACRO": Step(4, "STABILIZE", False, ("4:No such mode 29",)),
        },
        "set_armed_before_ready": {
            "RTL": Step(4, "STABILIZE", True, ("4:Mode change to RTL failed: requires position",)),
            "SMART_RTL": Step(
                4, "STABILIZE", True, ("4:Mode change to SMARTRTL failed: requires position",)
            ),
            "STABILIZE": Step(0, "STABILIZE", True, ()),
            "ACRO": Step(0, "ACRO", True, ()),
            "ALT_HOLD": Step(0, "ALT_HOLD", True, ()),
            "AUTO": Step(
                4, "STABILIZE", True, ("4:Mode change to AUTO failed: requires position",)
            ),
            "GUIDED": Step(
                4, "STABILIZE", True, ("4:Mode change to GUIDED failed: requires position",)
            ),
            "LOITER": Step(
                4, "STABILIZE", True, ("4:Mode change to LOITER failed: requires position",)
            ),
            "CIRCLE": Step(
                4, "STABILIZE", True, ("4:Mode change to CIRCLE failed: requires position",)
            ),
            "LAND": Step(0, "LAND", False, ("6:Disarming motors",)),
            "DRIFT": Step(
                4, "STABILIZE", True, ("4:Mode change to DRIFT failed: requires position",)
            ),
            "SPORT": Step(4, "STABILIZE", True, ("4:No such mode 13",)),
            "FLIP": Step(4, "STABILIZE", True, ("4:Mode change to FLIP failed: init failed",)),
            "AUTOTUNE": Step(
                4, "STABILIZE", True, ("4:Mode change to AUTOTUNE failed: init failed",)
            ),
            "POSHOLD": Step(
                4, "STABILIZE", True, ("4:Mode change to POSHOLD failed: requires position",)
            ),
            "BRAKE": Step(
                4, "STABILIZE", True, ("4:Mode change to BRAKE failed: requires position",)
            ),
            "THROW": Step(
                4, "STABILIZE", True, ("4:Mode change to THROW failed: requires position",)
            ),
            "AVOID_ADSB": Step(
                4, "STABILIZE", True, ("4:Mode change to AVOID_ADSB failed: requires position",)
            ),
            "GUIDED_NOGPS": Step(0, "GUIDED_NOGPS", True, ()),
            "FLOWHOLD": Step(
                4, "STABILIZE", True, ("4:Mode change to FLOWHOLD failed: init failed",)
            ),
            "FOLLOW": Step(
                4, "STABILIZE", True, ("4:Mode change to FOLLOW failed: requires position",)
            ),
            "ZIGZAG": Step(
                4, "STABILIZE", True, ("4:Mode change to ZIGZAG failed: requires position",)
            ),
            "SYSTEMID": Step(
                4,
                "STABILIZE",
                True,
                (
                    "4:No axis selected, SID_AXIS = 0",
                    "4:Mode change to SYSTEMID failed: init failed",
                ),
            ),
            "AUTOROTATE": Step(4, "STABILIZE", True, ("4:No such mode 26",)),
            "AUTO_RTL": Step(
                4,
                "STABILIZE",
                True,
                (
                    "4:Unable to start landing sequence",
                    "4:Mode change to AUTO RTL failed: No return path or landing sequence found",
                ),
            ),
            "TURTLE": Step(4, "STABILIZE", True, ("4:Mode change to TURTLE failed: init failed",)),
            "RATE_ACRO": Step(4, "STABILIZE", True, ("4:No such mode 29",)),
        },
        "set_ready": {
            "STABILIZE": Step(0, "STABILIZE", False, ()),
            "ACRO": Step(0, "ACRO", False, ()),
            "ALT_HOLD": Step(0, "ALT_HOLD", False, ()),
            "AUTO": Step(0, "AUTO", False, ()),
            "GUIDED": Step(0, "GUIDED", False, ()),
            "LOITER": Step(0, "LOITER", False, ()),
            "RTL": Step(0, "RTL", False, ()),
            "CIRCLE": Step(0, "CIRCLE", False, ()),
            "LAND": Step(0, "LAND", False, ()),
            "DRIFT": Step(0, "DRIFT", False, ()),
            "SPORT": Step(4, "STABILIZE", False, ("4:No such mode 13",)),
            "FLIP": Step(4, "STABILIZE", False, ("4:Mode change to FLIP failed: init failed",)),
            "AUTOTUNE": Step(
                4, "STABILIZE", False, ("4:Mode change to AUTOTUNE failed: init failed",)
            ),
            "POSHOLD": Step(0, "POSHOLD", False, ()),
            "BRAKE": Step(0, "BRAKE", False, ()),
            "THROW": Step(0, "THROW", False, ()),
            "AVOID_ADSB": Step(0, "AVOID_ADSB", False, ()),
            "GUIDED_NOGPS": Step(0, "GUIDED_NOGPS", False, ()),
            "SMART_RTL": Step(0, "SMART_RTL", False, ()),
            "FLOWHOLD": Step(
                4, "STABILIZE", False, ("4:Mode change to FLOWHOLD failed: init failed",)
            ),
            "FOLLOW": Step(
                4,
                "STABILIZE",
                False,
                ("4:Set FOLL_ENABLE = 1", "4:Mode change to FOLLOW failed: init failed"),
            ),
            "ZIGZAG": Step(0, "ZIGZAG", False, ()),
            "SYSTEMID": Step(
                4,
                "STABILIZE",
                False,
                (
                    "4:No axis selected, SID_AXIS = 0",
                    "4:Mode change to SYSTEMID failed: init failed",
                ),
            ),
            "AUTOROTATE": Step(4, "STABILIZE", False, ("4:No such mode 26",)),
            "AUTO_RTL": Step(
                4,
                "STABILIZE",
                False,
                (
                    "4:Unable to start landing sequence",
                    "4:Mode change to AUTO RTL failed: No return path or landing sequence found",
                ),
            ),
            "TURTLE": Step(4, "STABILIZE", False, ("4:Mode change to TURTLE failed: init failed",)),
            "RATE_ACRO": Step(4, "STABILIZE", False, ("4:No such mode 29",)),
        },
        "arm_ready": {
            "STABILIZE": Step(0, "STABILIZE", True, ("6:Arming motors",)),
            "ACRO": Step(0, "ACRO", True, ("6:Arming motors",)),
            "ALT_HOLD": Step(0, "ALT_HOLD", True, ("6:Arming motors",)),
            "AUTO": Step(4, "AUTO", False, ("2:Arm: Mode requires mission",)),
            "GUIDED": Step(0, "GUIDED", True, ("6:Arming motors",)),
            "LOITER": Step(0, "LOITER", True, ("6:Arming motors",)),
            "RTL": Step(4, "RTL", False, ("2:Arm: RTL mode not armable",)),
            "CIRCLE": Step(4, "CIRCLE", False, ("2:Arm: CIRCLE mode not armable",)),
            "LAND": Step(4, "LAND", False, ("2:Arm: LAND mode not armable",)),
            "DRIFT": Step(0, "DRIFT", True, ("6:Arming motors",)),
            "POSHOLD": Step(0, "POSHOLD", True, ("6:Arming motors",)),
            "BRAKE": Step(4, "BRAKE", False, ("2:Arm: BRAKE mode not armable",)),
            "THROW": Step(0, "THROW", True, ("6:Arming motors", "6:waiting for throw")),
            "AVOID_ADSB": Step(4, "AVOID_ADSB", False, ("2:Arm: AVOID_ADSB mode not armable",)),
            "GUIDED_NOGPS": Step(0, "GUIDED_NOGPS", True, ("6:Arming motors",)),
            "SMART_RTL": Step(4, "SMART_RTL", False, ("2:Arm: SMARTRTL mode not armable",)),
            "ZIGZAG": Step(0, "ZIGZAG", True, ("6:Arming motors",)),
        },
        "set_armed_ready": {
            "STABILIZE": Step(0, "STABILIZE", True, ()),
            "ACRO": Step(0, "ACRO", True, ()),
            "ALT_HOLD": Step(0, "ALT_HOLD", True, ()),
            "AUTO": Step(4, "STABILIZE", True, ("4:Mode change to AUTO failed: init failed",)),
            "GUIDED": Step(0, "GUIDED", True, ()),
            "LOITER": Step(0, "LOITER", True, ()),
            "RTL": Step(0, "RTL", True, ()),
            "CIRCLE": Step(0, "CIRCLE", True, ()),
            "LAND": Step(0, "LAND", False, ("6:Disarming motors",)),
            "DRIFT": Step(0, "DRIFT", True, ()),
            "SPORT": Step(4, "STABILIZE", True, ("4:No such mode 13",)),
            "FLIP": Step(4, "STABILIZE", True, ("4:Mode change to FLIP failed: init failed",)),
            "AUTOTUNE": Step(
                4, "STABILIZE", True, ("4:Mode change to AUTOTUNE failed: init failed",)
            ),
            "POSHOLD": Step(0, "POSHOLD", True, ()),
            "BRAKE": Step(0, "BRAKE", True, ()),
            "THROW": Step(4, "STABILIZE", True, ("4:Mode change to THROW failed: init failed",)),
            "AVOID_ADSB": Step(0, "AVOID_ADSB", True, ()),
            "GUIDED_NOGPS": Step(0, "GUIDED_NOGPS", True, ()),
            "SMART_RTL": Step(0, "SMART_RTL", True, ()),
            "FLOWHOLD": Step(
                4, "STABILIZE", True, ("4:Mode change to FLOWHOLD failed: init failed",)
            ),
            "FOLLOW": Step(
                4,
                "STABILIZE",
                True,
                ("4:Set FOLL_ENABLE = 1", "4:Mode change to FOLLOW failed: init failed"),
            ),
            "ZIGZAG": Step(0, "ZIGZAG", True, ()),
            "SYSTEMID": Step(
                4,
                "STABILIZE",
                True,
                (
                    "4:No axis selected, SID_AXIS = 0",
                    "4:Mode change to SYSTEMID failed: init failed",
                ),
            ),
            "AUTOROTATE": Step(4, "STABILIZE", True, ("4:No such mode 26",)),
            "AUTO_RTL": Step(
                4,
                "STABILIZE",
                True,
                (
                    "4:Unable to start landing sequence",
                    "4:Mode change to AUTO RTL failed: No return path or landing sequence found",
                ),
            ),
            "TURTLE": Step(4, "STABILIZE", True, ("4:Mode change to TURTLE failed: init failed",)),
            "RATE_ACRO": Step(4, "STABILIZE", True, ("4:No such mode 29",)),
        },
    },
    "plane": {
        "set_before_ready": {
            "RTL": Step(0, "RTL", False, ()),
            "MANUAL": Step(0, "MANUAL", False, ()),
            "CIRCLE": Step(0, "CIRCLE", False, ()),
            "STABILIZE": Step(0, "STABILIZE", False, ()),
            "TRAINING": Step(0, "TRAINING", False, ()),
            "ACRO": Step(0, "ACRO", False, ()),
            "FBWA": Step(0, "FBWA", False, ()),
            "FBWB": Step(0, "FBWB", False, ()),
            "CRUISE": Step(0, "CRUISE", False, ()),
            "AUTOTUNE": Step(
                0, "AUTOTUNE", False, ("6:Started autotune", "6:Autotuning roll pitch yaw")
            ),
            "AUTO": Step(0, "RTL", False, ("6:Mission complete, changing mode to RTL",)),
            "LOITER": Step(0, "LOITER", False, ()),
            "TAKEOFF": Step(0, "TAKEOFF", False, ()),
            "AVOID_ADSB": Step(0, "AVOID_ADSB", False, ()),
            "GUIDED": Step(0, "GUIDED", False, ()),
            "INITIALISING": Step(4, "MANUAL", False, ("4:Flight mode change failed",)),
            "QSTABILIZE": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "QHOVER": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "QLOITER": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "QLAND": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "QRTL": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "QAUTOTUNE": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "QACRO": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "THERMAL": Step(4, "MANUAL", False, ("4:Flight mode change failed",)),
            "LOITERALTQLAND": Step(0, "LOITERALTQLAND", False, ()),
            "AUTOLAND": Step(
                4, "MANUAL", False, ("4:Must already be flying!", "4:Flight mode change failed")
            ),
        },
        "set_armed_before_ready": {
            "RTL": Step(0, "RTL", True, ()),
            "MANUAL": Step(0, "MANUAL", True, ()),
            "CIRCLE": Step(0, "CIRCLE", True, ()),
            "STABILIZE": Step(0, "STABILIZE", True, ()),
            "TRAINING": Step(0, "TRAINING", True, ()),
            "ACRO": Step(0, "ACRO", True, ()),
            "FBWA": Step(0, "FBWA", True, ()),
            "FBWB": Step(0, "FBWB", True, ()),
            "CRUISE": Step(0, "CRUISE", True, ()),
            "AUTOTUNE": Step(
                0, "AUTOTUNE", True, ("6:Started autotune", "6:Autotuning roll pitch yaw")
            ),
            "LOITER": Step(0, "LOITER", True, ()),
            "AVOID_ADSB": Step(0, "AVOID_ADSB", True, ()),
            "GUIDED": Step(0, "GUIDED", True, ()),
            "INITIALISING": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "QSTABILIZE": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "QHOVER": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "QLOITER": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "QLAND": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "QRTL": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "QAUTOTUNE": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "QACRO": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "THERMAL": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "LOITERALTQLAND": Step(0, "LOITERALTQLAND", True, ()),
            "AUTOLAND": Step(
                4, "MANUAL", True, ("4:Must already be flying!", "4:Flight mode change failed")
            ),
        },
        "set_ready": {
            "MANUAL": Step(0, "MANUAL", False, ()),
            "CIRCLE": Step(0, "CIRCLE", False, ()),
            "STABILIZE": Step(0, "STABILIZE", False, ()),
            "TRAINING": Step(0, "TRAINING", False, ()),
            "ACRO": Step(0, "ACRO", False, ()),
            "FBWA": Step(0, "FBWA", False, ()),
            "FBWB": Step(0, "FBWB", False, ()),
            "CRUISE": Step(0, "CRUISE", False, ()),
            "AUTOTUNE": Step(
                0, "AUTOTUNE", False, ("6:Started autotune", "6:Autotuning roll pitch yaw")
            ),
            "AUTO": Step(0, "RTL", False, ("6:Mission complete, changing mode to RTL",)),
            "RTL": Step(0, "RTL", False, ()),
            "LOITER": Step(0, "LOITER", False, ()),
            "TAKEOFF": Step(0, "TAKEOFF", False, ()),
            "AVOID_ADSB": Step(0, "AVOID_ADSB", False, ()),
            "GUIDED": Step(0, "GUIDED", False, ()),
            "INITIALISING": Step(4, "MANUAL", False, ("4:Flight mode change failed",)),
            "QSTABILIZE": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "QHOVER": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "QLOITER": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "QLAND": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "QRTL": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "QAUTOTUNE": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "QACRO": Step(4, "MANUAL", False, ("6:Q_ENABLE 0",)),
            "THERMAL": Step(4, "MANUAL", False, ("4:Flight mode change failed",)),
            "LOITERALTQLAND": Step(0, "LOITERALTQLAND", False, ()),
            "AUTOLAND": Step(
                4, "MANUAL", False, ("4:Must already be flying!", "4:Flight mode change failed")
            ),
        },
        "arm_ready": {
            "MANUAL": Step(0, "MANUAL", True, ("6:Throttle armed",)),
            "CIRCLE": Step(0, "CIRCLE", True, ("6:Throttle armed",)),
            "STABILIZE": Step(0, "STABILIZE", True, ("6:Throttle armed",)),
            "TRAINING": Step(0, "TRAINING", True, ("6:Throttle armed",)),
            "ACRO": Step(0, "ACRO", True, ("6:Throttle armed",)),
            "FBWA": Step(0, "FBWA", True, ("6:Throttle armed",)),
            "FBWB": Step(0, "FBWB", True, ("6:Throttle armed",)),
            "CRUISE": Step(0, "CRUISE", True, ("6:Throttle armed",)),
            "AUTOTUNE": Step(0, "AUTOTUNE", True, ("6:Throttle armed",)),
            "RTL": Step(4, "RTL", False, ("2:Arm: RTL mode not armable",)),
            "LOITER": Step(0, "LOITER", True, ("6:Throttle armed",)),
            "AVOID_ADSB": Step(0, "AVOID_ADSB", True, ("6:Throttle armed",)),
            "GUIDED": Step(0, "GUIDED", True, ("6:Throttle armed",)),
            "LOITERALTQLAND": Step(0, "LOITERALTQLAND", True, ("6:Throttle armed",)),
        },
        "set_armed_ready": {
            "MANUAL": Step(0, "MANUAL", True, ()),
            "CIRCLE": Step(0, "CIRCLE", True, ()),
            "STABILIZE": Step(0, "STABILIZE", True, ()),
            "TRAINING": Step(0, "TRAINING", True, ()),
            "ACRO": Step(0, "ACRO", True, ()),
            "FBWA": Step(0, "FBWA", True, ()),
            "FBWB": Step(0, "FBWB", True, ()),
            "CRUISE": Step(0, "CRUISE", True, ()),
            "AUTOTUNE": Step(
                0, "AUTOTUNE", True, ("6:Started autotune", "6:Autotuning roll pitch yaw")
            ),
            "RTL": Step(0, "RTL", True, ()),
            "LOITER": Step(0, "LOITER", True, ()),
            "AVOID_ADSB": Step(0, "AVOID_ADSB", True, ()),
            "GUIDED": Step(0, "GUIDED", True, ()),
            "INITIALISING": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "QSTABILIZE": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "QHOVER": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "QLOITER": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "QLAND": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "QRTL": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "QAUTOTUNE": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "QACRO": Step(4, "MANUAL", True, ("6:Q_ENABLE 0",)),
            "THERMAL": Step(4, "MANUAL", True, ("4:Flight mode change failed",)),
            "LOITERALTQLAND": Step(0, "LOITERALTQLAND", True, ()),
            "AUTOLAND": Step(
                4, "MANUAL", True, ("4:Must already be flying!", "4:Flight mode change failed")
            ),
        },
    },
}

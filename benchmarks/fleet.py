"""Generate a large valid mission: N agents on the shipped platforms, varied behaviours.

Used by the benchmarks (and by tests that need a big mission). Deterministic:
the same N gives the same text.
"""

from __future__ import annotations

#: Platform by agent index modulo 4; each gets a behaviour that suits it.
PLATFORMS = ("anaconda", "dji_f450", "super_cub", "traxxas_slash")


SPACING_M = 250
"""Between neighbouring vehicles' starts, on a grid ten wide: room for a plane's survey
(200 m north) and its loiter circle in its own cell, so that the fleet keeps its 5 m
separation and the dry run's safety judgement passes it (at 40 m the planes' circles
crossed: twelve near misses in a minute)."""

XBEE_SPACING_M = 140
"""The grid on an XBee mesh: fifty agents within the radio's mile of the station
(E-RADIO-RANGE), closer than a safe fleet would fly. Those fleets load the link (its
budget, the dry run's reproducibility under faults); their dry runs report near misses."""

#: Aircraft start in flight, handed over by their pilots at this height (``launch.airborne``);
#: rovers start on the ground.
HANDOVER_HEIGHT_M = {"anaconda": 80, "dji_f450": 20, "super_cub": 60}
"""The Anacondas survey at 80 m and the Super Cubs circle at 60 m: a survey's last loiter
circle reaches into the next cell north, where a Super Cub circles."""

#: Every vehicle's telemetry by default: heartbeat and status bundle into one packet a
#: second; the behaviour's state goes to the station only.
LIGHT_TELEMETRY = "{heartbeat: 1, agent_status: 1, behavior_state: {rate_hz: 0.5, to: [mcs]}}"
#: The schedule docs/performance.md's link-budget figures were measured with.
HEAVY_TELEMETRY = "{heartbeat: 1, agent_status: 2, behavior_state: 1}"


def fleet_mission(
    agents: int, loop_hz: float = 10, radio: str = "udp_lan", telemetry: str = LIGHT_TELEMETRY
) -> str:
    """A mission with one station and ``agents - 1`` vehicles, as YAML text.

    The radio defaults to the UDP LAN profile: a hundred agents' telemetry is far
    beyond the 33 kbps of an XBee mesh (clark validate says so, E-LINK-BUDGET). On the
    LAN the vehicles start :data:`SPACING_M` apart, on XBees :data:`XBEE_SPACING_M`.
    """

    spacing_m = SPACING_M if radio == "udp_lan" else XBEE_SPACING_M

    def address(i: int) -> str:
        if radio == "udp_lan":
            return f'{{profile: udp_lan, address: "127.0.0.1:{15000 + i}"}}'
        return f'{{address: "0013A2004000{i:04X}"}}'

    lines = [
        "clark: 1",
        "mission:",
        "  id: 4242",
        f"  name: fleet-{agents}",
        f"  loop_hz: {loop_hz}",
        "  origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}",
        "agents:",
        "  mcs:",
        "    id: 1",
        "    profile: mcs_laptop",
        f"    hardware: {{radio: {address(1)}}}",
        "    telemetry: {heartbeat: 1}",
    ]
    for i in range(2, agents + 1):
        platform = PLATFORMS[i % len(PLATFORMS)]
        name = f"v{i:03d}"
        east = (i % 10) * spacing_m
        north = (i // 10) * spacing_m
        lines += [
            f"  {name}:",
            f"    id: {i}",
            f"    profile: {platform}",
            f"    hardware: {{radio: {address(i)}}}",
            f"    telemetry: {telemetry}",
        ]
        if platform in HANDOVER_HEIGHT_M:  # aircraft: their pilots hand them over in flight
            lines += [
                "    launch: {airborne: true}",
                f"    position: [{north}, {east}, {HANDOVER_HEIGHT_M[platform]}]",
            ]
        else:  # rovers start on the ground, each on its own spot
            lines += [f"    position: [{north}, {east}]"]
        if i % 4 == 0:  # anaconda: survey block with photos
            survey_m = HANDOVER_HEIGHT_M["anaconda"]
            lines += [
                "    behavior:",
                "      initial: survey",
                "      states:",
                "        survey:",
                "          use: survey_with_photos",
                f"          with: {{waypoints: [[{north}, {east}, {survey_m}],"
                f" [{north + 200}, {east}, {survey_m}]], tolerance_m: 75}}",
                "          transitions: {done: doublet}",
                "        doublet: {use: aileron_doublet, transitions: {done: loiter}}",
                "        loiter: {use: hold, final: true}",
            ]
        elif i % 4 == 2:  # super_cub: the system-identification sequence on activation
            lines += [
                "    behavior:",
                "      initial: piloted",
                "      states:",
                "        piloted: {use: wait, transitions: {activate: excite}}",
                "        excite: {use: system_id_sequence, transitions: {done: piloted,"
                " deactivate: piloted}}",
            ]
        elif i % 4 == 1:  # dji_f450: follow the previous vehicle
            target = f"v{i - 1:03d}"
            lines += [
                "    behavior:",
                "      initial: idle",
                "      states:",
                "        idle: {use: hold, transitions: {activate: chase}}",
                # 12 m behind it, done within 6 m: never inside the 5 m separation
                f"        chase: {{use: follow_agent, with: {{target: {target},"
                " offset: {north_m: -12}, tolerance_m: 6}, transitions: {done: parked}}",
                "        parked: {use: hold, final: true}",
            ]
        else:  # traxxas_slash: a looping tour
            lines += [
                "    behavior:",
                "      use: waypoint_tour",
                f"      with: {{loop: true, waypoints: [[{north}, {east}], [{north + 30}, {east}],"
                f" [{north + 30}, {east + 30}]]}}",
            ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    # python benchmarks/fleet.py N [LOOP_HZ] > fleet.yaml: a generated fleet to try things on.
    import sys

    if len(sys.argv) not in (2, 3) or not sys.argv[1].isdigit() or int(sys.argv[1]) < 2:
        sys.exit("usage: python benchmarks/fleet.py AGENTS [LOOP_HZ] > fleet.yaml  (AGENTS >= 2)")
    sys.stdout.write(
        fleet_mission(int(sys.argv[1]), loop_hz=float(sys.argv[2]) if len(sys.argv) == 3 else 10)
    )

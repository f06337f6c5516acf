#!/usr/bin/env bash
# The cooperative-follow rehearsal of docs/flight.md (section 4b) in one script: each
# rover's autopilot (ArduPilot SITL with CLARK_SITL set, else the simulated autopilot),
# the station and both rovers' `clark run`, on UDP radios at free ports, logs in
# logs/rehearsal. Each clark run is given the connection its autopilot printed: SITL picks
# its instance (and so its port) when it starts, so fixed ports could hand one rover's
# mission computer the other's autopilot. Ctrl-C stops everything.
#
#   tools/rehearse.sh [MISSION]          (default missions/cooperative_follow.yaml)
set -euo pipefail
M=${1:-missions/cooperative_follow.yaml}
LOGS=${LOGS:-logs/rehearsal}
WORK=$(mktemp -d)
trap 'trap "" TERM; kill -TERM 0 2>/dev/null; wait 2>/dev/null; rm -rf "$WORK"' EXIT
if [ -n "${CLARK_SITL:-}" ]; then AUTOPILOT=(--autopilot sitl); else AUTOPILOT=(--autopilot sim); fi

free_port() { python3 -c 'import socket; s=socket.socket(socket.AF_INET, socket.SOCK_DGRAM); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }

# The autopilots, one after the other: each prints where its clark run connects.
declare -A CONNECT
for rover in slash_a slash_b; do
  LISTEN=()
  if [ "${AUTOPILOT[1]}" = sim ]; then LISTEN=(--listen "127.0.0.1:$(free_port)"); fi
  clark autopilot-sim "$M" --agent "$rover" "${AUTOPILOT[@]}" "${LISTEN[@]}" > "$WORK/$rover.ap" 2>&1 &
  until CONNECT[$rover]=$(grep -o -m1 -- '--autopilot-connection [^ ]*' "$WORK/$rover.ap" | cut -d' ' -f2) \
        && [ -n "${CONNECT[$rover]}" ]; do
    if ! kill -0 $! 2>/dev/null; then cat "$WORK/$rover.ap"; exit 2; fi
    sleep 0.5
  done
  echo "$rover: autopilot at ${CONNECT[$rover]}"
  tail -n +1 -f "$WORK/$rover.ap" | sed "s/^/[$rover autopilot] /" &
done

# One free UDP port per agent's radio; each clark run names the others as its peers.
declare -A PORT=([mcs]=$(free_port) [slash_a]=$(free_port) [slash_b]=$(free_port))
peers() { for other in mcs slash_a slash_b; do [ "$other" = "$1" ] || echo "--peer $other=127.0.0.1:${PORT[$other]}"; done; }

# The station plays the mission's operator script; its times count from its own start.
clark run "$M" --agent mcs --logs "$LOGS" --script --no-console --plain --no-payload \
  --radio udp --radio-address "127.0.0.1:${PORT[mcs]}" $(peers mcs) 2>&1 | sed 's/^/[mcs] /' &
for rover in slash_a slash_b; do
  clark run "$M" --agent "$rover" --logs "$LOGS" --plain --no-payload \
    --autopilot-connection "${CONNECT[$rover]}" \
    --radio udp --radio-address "127.0.0.1:${PORT[$rover]}" $(peers "$rover") 2>&1 | sed "s/^/[$rover] /" &
done
echo "rehearsing $M: logs in $LOGS; Ctrl-C stops every process"
wait

#!/usr/bin/env bash
# Runs a command inside the private network namespace that `unshare -n` created around this
# script: only a loopback interface exists, so DDS discovery cannot reach or hear any other
# host or test run. Loopback starts down in a new namespace; bring it up with multicast.
set -euo pipefail
ip link set lo up
ip link set lo multicast on
ip route add 224.0.0.0/4 dev lo 2>/dev/null || true
exec "$@"

#!/usr/bin/env bash
# Fails when a process started by a test run outlives it: every process whose environment holds
# LIGHTPORT_TEST_SESSION=<SESSION> (scripts/test.sh gives that marker to `cargo test`; children
# inherit it: servers, node drivers, browsers, nginx). A process still there after a grace period
# is listed with its command line and killed, and the script exits 1.
#
#   scripts/leftover-processes.sh SESSION
set -euo pipefail
session=${1:?usage: scripts/leftover-processes.sh SESSION}
marker="LIGHTPORT_TEST_SESSION=$session"

marked() {
    local environ pid
    for environ in /proc/[0-9]*/environ; do
        pid=${environ#/proc/}
        pid=${pid%/environ}
        [ "$pid" = "$$" ] && continue
        if { tr '\0' '\n' <"$environ"; } 2>/dev/null | grep -qxF "$marker"; then
            echo "$pid"
        fi
    done
}

# Children told to exit with their parent need a moment after it ends.
for _ in $(seq 50); do
    left=$(marked)
    [ -z "$left" ] && exit 0
    sleep 0.2
done
echo "error: processes started by the tests are still running after they ended:" >&2
for pid in $left; do
    printf '  %s: %s\n' "$pid" "$({ tr '\0' ' ' <"/proc/$pid/cmdline"; } 2>/dev/null | cut -c1-300)" >&2
done
for pid in $left; do
    kill -9 "$pid" 2>/dev/null || true
done
exit 1

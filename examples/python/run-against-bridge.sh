#!/usr/bin/env bash
# Runs bridge_client.py against a real `motorwire bridge --bus sim`, once over
# its local socket and once over TCP with a token, and checks that a wrong
# token is turned away. Exits non-zero if anything fails. CI runs it; so can
# you: `bash examples/python/run-against-bridge.sh [path/to/motorwire]`.
set -euo pipefail
cd "$(dirname "$0")/../.."

mw=${1:-motorwire}
map=fixtures/maps/demo-arm.toml
client=examples/python/bridge_client.py
dir=$(mktemp -d)
bridge_pid=
cleanup() {
    if [ -n "$bridge_pid" ]; then kill "$bridge_pid" 2>/dev/null || true; fi
    rm -rf "$dir"
}
trap cleanup EXIT

# Waits until $1 exists (a socket) or "$2" succeeds, at most 10 s.
wait_until() {
    for _ in $(seq 100); do
        if eval "$1"; then return 0; fi
        sleep 0.1
    done
    echo "the bridge did not come up"; cat "$dir/bridge.err"; exit 1
}

# Stops the bridge with SIGTERM: it deactivates the joints and exits 143.
stop_bridge() {
    kill -TERM "$bridge_pid"
    set +e
    wait "$bridge_pid"
    status=$?
    set -e
    bridge_pid=
    [ "$status" -eq 143 ] || { echo "bridge exited $status, expected 143"; cat "$dir/bridge.err"; exit 1; }
}

echo "--- over a local socket"
"$mw" bridge --map "$map" --bus sim --feedback-hz 0 --input "unix:$dir/bridge.sock" \
    > "$dir/bridge.out" 2> "$dir/bridge.err" &
bridge_pid=$!
wait_until "[ -S '$dir/bridge.sock' ]"
python3 "$client" --unix "$dir/bridge.sock"
echo "--- a policy streaming setpoints at 100 Hz"
python3 examples/python/stream_policy.py --unix "$dir/bridge.sock" --hz 100 --seconds 2
echo "--- a policy streaming three joints in one line a tick at 100 Hz"
python3 examples/python/stream_policy.py --unix "$dir/bridge.sock" --hz 100 --seconds 2 \
    --with shoulder_pitch --with shoulder_roll
stop_bridge

echo "--- over TCP, with a token"
umask 077
head -c 24 /dev/urandom | od -An -tx1 | tr -d ' \n' > "$dir/token"
port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
"$mw" bridge --map "$map" --bus sim --feedback-hz 0 --input "tcp:127.0.0.1:$port" --token-file "$dir/token" \
    > "$dir/bridge.out" 2> "$dir/bridge.err" &
bridge_pid=$!
wait_until "python3 -c 'import socket; socket.create_connection((\"127.0.0.1\", $port), 1).close()' 2>/dev/null"
python3 "$client" --tcp "127.0.0.1:$port" --token-file "$dir/token"

# A wrong token: one error line, and nothing executed.
echo "not-the-token-at-all" > "$dir/wrong"
set +e
python3 "$client" --tcp "127.0.0.1:$port" --token-file "$dir/wrong" 2> "$dir/wrong.err"
status=$?
set -e
grep -q '"kind": "unauthorized"' "$dir/wrong.err" && [ "$status" -eq 1 ] \
    || { echo "a wrong token: exit $status"; cat "$dir/wrong.err"; exit 1; }
echo "ok: a wrong token is refused (unauthorized)"
stop_bridge
echo "python client: passed over unix and tcp"

#!/usr/bin/env bash
# Writes the seed corpora from the golden vectors: WIRE-FACTS §1.4, the
# per-variant goldens of motorwire-irpc, the compact goldens and the WIA
# fixtures. Run from the repository root; writes fuzz/corpus/<target>/.
set -euo pipefail
cd "$(dirname "$0")/.."
out=fuzz/corpus
rm -rf "$out"
mkdir -p "$out"/{compact_decode,compact_feedback_decode,irpc_decode_v1,irpc_decode_v2_0,irpc_decode_v2_1,irpc_decode_v2_2,irpc_decode_frame,wia_validate,orion_parse,moteus_decode,servo_feetech_status,servo_dynamixel_status}
# Hex digits (spaces allowed) to bytes, with bash's printf alone.
unhex() { local h; h=$(printf '%s' "$1" | tr -d ' \n' | sed 's/../\\x&/g'); printf '%b' "$h"; }
i=0
# Per-variant goldens: "v2.0 SetTargetV2: 00 10 ..."
while IFS= read -r line; do
    case "$line" in '#'*|'') continue ;; esac
    label=${line%%:*}; bytes=${line#*:}
    version=${label%% *}
    target=irpc_decode_$(printf '%s' "$version" | tr . _)
    i=$((i + 1))
    unhex "$bytes" > "$out/$target/golden-$i"
    unhex "$bytes" > "$out/irpc_decode_frame/golden-$i"
done < crates/motorwire-irpc/tests/every_variant.golden
# WIRE-FACTS §1.4 (v2.0 and v2.1).
for h in \
    "00 10 2a 05 00 00 b4 42 00 00 c8 42 00 00 00 00 00 00 fa 43 00 00 fa 43 00 00 fa 44 01 00 00 00 00 00 00 00 00" \
    "00 10 05 00 00 00 b4 42 00 00 16 43" "00 10 01 01" "10 00 2a 08 2a" "10 00 2a 09 2a ff 01" "00 ff ff 03 00 0a"; do
    i=$((i + 1)); unhex "$h" > "$out/irpc_decode_v2_0/facts-$i"
done
unhex "00 10 2a 05 00 00 b4 42 00 00 c8 42 00 00 00 00 00 00 fa 43 00 00 fa 43 00 00 fa 44 01 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00" \
    > "$out/irpc_decode_frame/doc-example-48"
unhex "10 00 2a 12 2a" > "$out/irpc_decode_v2_1/facts-ack"
unhex "00 ff ff 03 00 14" > "$out/irpc_decode_v2_1/facts-armready"
# Compact goldens.
unhex "cf 43 3b f3 00 f4 51 c2 8c 01 00 00 01 00 00 00 00 00 34 42 58 02 ff ff" > "$out/compact_decode/shoulder-pitch"
unhex "22 cb 57 81 08 07 06 05 04 03 02 01 03 e1 00 00 00 00 20 c0 fe ff d2 04" > "$out/compact_decode/elbow-flags"
# Compact feedback golden (crates/motorwire-compact/tests/feedback.rs).
unhex "22 cb 57 81 60 e3 16 00 00 00 00 00 00 00 34 42 00 00 20 c0 00 00 00 00 00 00 c0 3f 00 00 00 40 00 00 c0 41 00 00 c8 41 59 00 64 00 00 00 00 00" > "$out/compact_feedback_decode/elbow"
# WIA fixtures.
for f in fixtures/wia/valid/*.json fixtures/wia/invalid/*.json; do
    cp "$f" "$out/wia_validate/$(basename "$f")"
done
# The commonest line a controller writes: one flat command (the one-pass
# reading's shape), with a fraction, a negative and a priority.
printf '%s' '{"motor_id":"elbow","timestamp":1704067200000,"control_mode":"position","setpoint":-30.25,"velocity_limit":100,"priority":7}' \
    > "$out/wia_validate/flat-command"
# The Orion document's examples.
printf '%s' '{"ID":32,"MODE":1,"DATA":{"TRM":200,"LAA":1,"UAA":1,"AEM":400}}' > "$out/orion_parse/direct"
printf '%s' '{"ID":32,"MODE":2,"DATA":3}' > "$out/orion_parse/unfold"
printf '%s' '{"ID":32,"MODE":1,"DATA":{"TRM":[200,65,0],"LAA":[1,50,0],"UAA":[1,45,0],"AEM":[400,35,0]}}' > "$out/orion_parse/feedback"
printf '%s' '{"ID":32,"MODE":2,"DATA":{"CMDF":1}}' > "$out/orion_parse/cmdf"
printf '%s' '{"ID":32}' > "$out/orion_parse/beacon"
# moteus replies (motorwire-moteus's golden tests: mjbots' Python library's
# readings of them), padded and cut.
i=0
for h in "21 00 0a 2d 01 00 00 00 3f 50 50 50" \
    "21 00 0a 26 01 ce 07 20 fd 29 03 0f 2e 00 00 31 82 02 03 50 50" \
    "26 01 00 80 00 80 31 b0 02 03 50 50" "21 00 0a 2d 01 00 00 00"; do
    i=$((i + 1)); unhex "$h" > "$out/moteus_decode/golden-$i"
done
# Servo status packets (motorwire-servo's doc examples): a Feetech read's
# answer after a stray byte, and a Dynamixel ping's answer.
unhex "00 ff ff 01 04 00 00 08 f2" > "$out/servo_feetech_status/read-answer"
unhex "ff ff fe ff ff 03 02 00 fa" > "$out/servo_feetech_status/noise-then-write-answer"
unhex "ff ff fd 00 01 07 00 55 00 b0 04 2e ed 54" > "$out/servo_dynamixel_status/ping-answer"
echo "seeds: $(find "$out" -type f | wc -l) files"

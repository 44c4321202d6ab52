#!/bin/sh
# g2l_train under signals (issue: lose nothing): SIGTERM writes a checkpoint and exits 143, and
# --resume finishes the run; SIGKILL at a random moment leaves a loadable last.g2l that is at
# most one checkpoint interval (one epoch here) behind, and --resume finishes the run.
# Usage: test_signals.sh BUILD_DIR SOURCE_DIR
set -u
B=$1
S=$2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
fail() { echo "FAIL: $*"; for f in "$T"/*.log; do echo "--- $f"; tail -5 "$f"; done; exit 1; }
TRAIN="$B/apps/g2l_train"
# Tiny settings: epochs of 96 samples (12 steps), no validation, a checkpoint every epoch.
SETS="--set train.epochs=6 --set train.samples_per_epoch=96 --set train.val_every=0 --set train.log_every=1 --set threads=2"
last_step() { tail -1 "$1/steps.jsonl" | sed 's/.*"step":\([0-9]*\).*/\1/'; }
ckpt_step() {  # global step stored in last.g2l (via the resume metadata, printed by --resume)
    grep -a -o '"global_step":[0-9]*' "$1/last.g2l" | head -1 | sed 's/.*://'
}

# 1. SIGTERM in the middle of an epoch.
"$TRAIN" --config "$S/configs/demo_cpu.json" --set "run_dir=$T/term" $SETS --quiet >"$T/term.log" 2>&1 &
pid=$!
i=0
while [ ! -s "$T/term/steps.jsonl" ] || [ "$(last_step "$T/term")" -lt 16 ]; do
    sleep 0.2; i=$((i + 1)); [ $i -lt 600 ] || fail "no training progress"
done
kill -TERM $pid
wait $pid
rc=$?
[ $rc -eq 143 ] || fail "SIGTERM: exit $rc, expected 143"
grep -q "checkpoint written" "$T/term.log" || fail "SIGTERM: no message"
t_log=$(last_step "$T/term")
t_ck=$(ckpt_step "$T/term")
[ "$t_ck" = "$t_log" ] || fail "SIGTERM: checkpoint at step $t_ck, log at $t_log"
"$TRAIN" --resume "$T/term" --quiet >"$T/term_resume.log" 2>&1 || fail "resume after SIGTERM failed"
[ "$(last_step "$T/term")" -eq 72 ] || fail "resumed run ended at step $(last_step "$T/term"), not 72"
# The log of the stopped run ended at the checkpoint with why it stopped (kept by the resume).
grep -q "\"event\":\"stopped\".*\"reason\":\"signal\".*\"step\":$t_log}" "$T/term/steps.jsonl" || fail "SIGTERM: no stopped record at step $t_log"
# --resume --set is written to the run's config.json (the directory says how it trains now).
"$TRAIN" --resume "$T/term" --set train.epochs=7 --max-steps 74 --quiet >"$T/term_more.log" 2>&1 || fail "resume with --set failed"
grep -q '"epochs": 7' "$T/term/config.json" || fail "--resume --set train.epochs=7 not in config.json"
[ "$(last_step "$T/term")" -eq 74 ] || fail "the run resumed with --max-steps 74 ended at step $(last_step "$T/term")"
grep -q '"reason":"max_steps","step":74}' "$T/term/steps.jsonl" || fail "no max_steps record at step 74"

# 2. SIGKILL at a random moment after the first checkpoint.
"$TRAIN" --config "$S/configs/demo_cpu.json" --set "run_dir=$T/kill" $SETS --quiet >"$T/kill.log" 2>&1 &
pid=$!
target=$(( 14 + $(od -An -N1 -tu1 /dev/urandom) % 40 ))  # a step between 14 and 53
i=0
while [ ! -s "$T/kill/steps.jsonl" ] || [ "$(last_step "$T/kill")" -lt $target ]; do
    sleep 0.05; i=$((i + 1)); [ $i -lt 3000 ] || fail "no training progress"
done
kill -KILL $pid
wait $pid 2>/dev/null
[ -f "$T/kill/last.g2l" ] || fail "SIGKILL at step $target: no last.g2l"
s_log=$(last_step "$T/kill")
s_ck=$(ckpt_step "$T/kill")
[ $((s_log - s_ck)) -le 12 ] || fail "SIGKILL: checkpoint at $s_ck, $((s_log - s_ck)) steps behind the log (> one epoch)"
"$TRAIN" --resume "$T/kill" --quiet >"$T/kill_resume.log" 2>&1 || fail "resume after SIGKILL failed"
ls "$T/kill" | grep -q '\.tmp' && fail "a temporary file of an interrupted write survived the resume"
[ "$(last_step "$T/kill")" -eq 72 ] || fail "resumed run ended at step $(last_step "$T/kill"), not 72"
# 3. One writer per run directory: while a run trains, --resume and --force on its directory are
#    refused naming the process (run.lock); once it stopped, --resume goes on.
#    The run trains at model.width 0.5 (the config file says 0.25): what --resume compares against
#    is the run's own config.json.
"$TRAIN" --config "$S/configs/demo_cpu.json" --set "run_dir=$T/lock" --set model.width=0.5 $SETS --quiet >"$T/lock.log" 2>&1 &
pid=$!
i=0
while [ ! -s "$T/lock/last.g2l" ]; do
    sleep 0.1; i=$((i + 1)); [ $i -lt 1200 ] || fail "no checkpoint to lock against"
done
"$TRAIN" --resume "$T/lock" --quiet >"$T/lock_resume.log" 2>&1
rc=$?
[ $rc -eq 1 ] || fail "--resume while the run trains: exit $rc, expected 1"
grep -q "is in use by another g2l_train (pid $pid)" "$T/lock_resume.log" || fail "--resume while the run trains: the other process is not named: $(cat "$T/lock_resume.log")"
"$TRAIN" --config "$S/configs/demo_cpu.json" --set "run_dir=$T/lock" $SETS --force --quiet >"$T/lock_force.log" 2>&1
rc=$?
[ $rc -eq 1 ] || fail "--force while the run trains: exit $rc, expected 1"
grep -q "is in use by another g2l_train (pid $pid)" "$T/lock_force.log" || fail "--force while the run trains: not refused by the lock: $(cat "$T/lock_force.log")"
kill -TERM $pid
wait $pid
# --resume refuses changes of what the weights mean, by --set or by a --config other than the
# run's own, naming the key; others go through.
"$TRAIN" --resume "$T/lock" --set model.width=0.25 --quiet >"$T/lock_width.log" 2>&1
rc=$?
[ $rc -eq 1 ] || fail "--resume --set model.width: exit $rc, expected 1"
grep -q "set model.width=0.25: the run's weights were trained with model.width = 0.5" "$T/lock_width.log" || fail "--resume --set model.width: $(cat "$T/lock_width.log")"
"$TRAIN" --resume "$T/lock" --set data.object_ids=[14,8] --quiet >"$T/lock_ids.log" 2>&1
rc=$?
[ $rc -eq 1 ] || fail "--resume with the object ids reordered: exit $rc, expected 1"
grep -q "data.object_ids" "$T/lock_ids.log" || fail "--resume with the object ids reordered: $(cat "$T/lock_ids.log")"
"$TRAIN" --config "$S/configs/demo_cpu.json" --resume "$T/lock" --quiet >"$T/lock_cfg.log" 2>&1
rc=$?
[ $rc -eq 1 ] || fail "--config (width 0.25) --resume of a width-0.5 run: exit $rc, expected 1"
grep -q "with --config .*demo_cpu.json (model.width = 0.25): the run's weights were trained with model.width = 0.5" "$T/lock_cfg.log" || fail "--config --resume of another width: $(cat "$T/lock_cfg.log")"
l_stop=$(ckpt_step "$T/lock")
"$TRAIN" --config "$S/configs/demo_cpu.json" --resume "$T/lock" --set model.width=0.5 --max-steps $((l_stop + 2)) --quiet >"$T/lock_after.log" 2>&1 || fail "--config --resume --set with the run's own width: $(cat "$T/lock_after.log")"
[ "$(last_step "$T/lock")" -eq $((l_stop + 2)) ] || fail "the run stopped at $l_stop, resumed with --max-steps $((l_stop + 2)), ended at step $(last_step "$T/lock")"
"$TRAIN" --resume "$T/lock" --max-steps $((l_stop + 4)) --quiet >"$T/lock_after2.log" 2>&1 || fail "--resume after the run stopped: $(cat "$T/lock_after2.log")"
echo "signals: SIGTERM at step $t_log checkpointed exactly; SIGKILL at step $target lost $((s_log - s_ck)) steps; both resumed to the end"

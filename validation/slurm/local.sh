#!/usr/bin/env bash
# Run ohd as a Slurm job array on a private single-node Slurm started on this machine, and check
# that the merged shards equal a single run byte for byte.
#
#     bash validation/slurm/local.sh           # the whole exercise (run as root, Debian)
#     bash validation/slurm/local.sh --smoke   # Slurm and the sbatch scripts only, with a
#                                              # stand-in for ohd that records its arguments
#
# What it does: installs slurm-wlm, munge and jq with apt-get if they are missing; builds ohd
# (cargo build --release) unless OHD names a binary; writes a private configuration under
# validation/slurm/.run/ (git-ignored; wiped at each start): a munge key and socket, slurm.conf on
# ports 16817/16818 of 127.0.0.1, state, spool and log directories. It never reads or changes
# /etc/slurm or /etc/munge and does not disturb a Slurm or munge already running here. It starts
# munged, slurmctld and slurmd in the foreground as background jobs of this script, waits for the
# node to be idle, submits ohd_array.sbatch as an array of SHARDS tasks and ohd_merge.sbatch with
# --dependency=afterok on it, waits for both, runs the same experiment once with plain `ohd run`,
# and compares: the same files, every data file identical (cmp), the same estimates in
# manifest.json and the rest of it equal but for timings, threads and invocation. It stops everything it started when it exits, on success or failure, and exits
# non-zero on any failure, with the tails of the daemons' logs when Slurm does not come up.
#
# Environment: SHARDS (array size, ≤ run.batches) [4], SAMPLES [4000000], SEED [7],
# CONFIG [configs/default.toml], OHD [target/release/ohd, built here], RUN_DIR [validation/slurm/.run].
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
smoke=0
case "${1:-}" in
    --smoke) smoke=1 ;;
    "") ;;
    *) echo "usage: $0 [--smoke]" >&2; exit 2 ;;
esac
shards="${SHARDS:-4}"
samples="${SAMPLES:-4000000}"
seed="${SEED:-7}"
config="${CONFIG:-$repo/configs/default.toml}"
run="${RUN_DIR:-$here/.run}"
ctld_port=16817   # not Slurm's default 6817/6818, so a real installation can run beside this one
slurmd_port=16818

step() { printf '\n== %s\n' "$*"; }
now() { date +%s.%N; }
secs() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", b - a }'; }

# ---------------------------------------------------------------------------------------------
# 1. Packages and the ohd binary
# ---------------------------------------------------------------------------------------------
step "packages"
need=()
for cmd in slurmctld slurmd sbatch; do command -v "$cmd" >/dev/null || need+=(slurm-wlm); done
command -v munged >/dev/null || need+=(munge)
command -v jq >/dev/null || need+=(jq)
if [ ${#need[@]} -gt 0 ]; then
    mapfile -t need < <(printf '%s\n' "${need[@]}" | sort -u)
    echo "installing ${need[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null
fi
echo "$(slurmctld -V), $(munged -V 2>&1 | head -n 1)"

if [ "$smoke" = 0 ]; then
    step "ohd"
    if [ -n "${OHD:-}" ]; then
        ohd="$OHD"
    else
        command -v cargo >/dev/null || { echo "cargo not found: install Rust (rustup) or set OHD=/path/to/ohd" >&2; exit 1; }
        target="${CARGO_TARGET_DIR:-$repo/target}"
        (cd "$repo" && cargo build --release --quiet)
        ohd="$target/release/ohd"
    fi
    ohd="$(cd "$(dirname "$ohd")" && pwd)/$(basename "$ohd")"   # absolute: jobs start elsewhere
    "$ohd" --version
    if ! "$ohd" run --help | grep -q -- '--shard' || ! "$ohd" merge --help >/dev/null 2>&1; then
        echo "$ohd has no \`run --shard\` or no \`merge\`: this exercise needs both" \
             "(\`$0 --smoke\` checks the Slurm side without them)" >&2
        exit 1
    fi
fi

# ---------------------------------------------------------------------------------------------
# 2. A private single-node cluster: munge key and socket, slurm.conf, directories
# ---------------------------------------------------------------------------------------------
step "private Slurm configuration in $run"
for pidfile in "$run"/munge/munged.pid "$run"/slurmctld.pid "$run"/slurmd.pid; do
    if [ -s "$pidfile" ] && kill -0 "$(cat "$pidfile")" 2>/dev/null; then
        echo "a daemon of an earlier local.sh is still running ($pidfile, pid $(cat "$pidfile")); stop it first" >&2
        exit 1
    fi
done
# RUN_DIR is wiped: only if it is empty or an earlier run of this script (marked by .local-sh-run).
if [ -d "$run" ] && [ -n "$(ls -A "$run")" ] && [ ! -f "$run/.local-sh-run" ]; then
    echo "RUN_DIR=$run is not empty and not an earlier local.sh run directory: refusing to wipe it" >&2
    exit 1
fi
rm -rf "$run"
mkdir -p "$run"/{state,spool,log,jobs,out}
touch "$run/.local-sh-run"
# munged insists that nobody but its owner can write to the directories of its key and socket
# and that everyone can reach the socket: 755 directory, 600 key.
mkdir -m 755 "$run/munge"
if command -v mungekey >/dev/null; then
    mungekey --create --keyfile="$run/munge/munge.key"
else
    dd if=/dev/urandom of="$run/munge/munge.key" bs=1024 count=1 status=none
fi
chmod 600 "$run/munge/munge.key"
sock="$run/munge/munge.socket"

node="$(hostname -s)"
cpus="$(nproc)"
# RealMemory in MB, a little under MemTotal: slurmd drains a node that has less than slurm.conf says.
mem_mb=$(awk '/^MemTotal:/ { printf "%d", $2 / 1024 * 0.95 }' /proc/meminfo)
conf="$run/slurm.conf"
cat > "$conf" <<EOF
# Written by validation/slurm/local.sh: a throwaway single-node cluster, everything under $run.
ClusterName=ohdlocal
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
# Root runs everything: no slurm user, no /etc or /var paths.
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$sock
CredType=cred/munge
StateSaveLocation=$run/state
SlurmdSpoolDir=$run/spool
SlurmctldPidFile=$run/slurmctld.pid
SlurmdPidFile=$run/slurmd.pid
SlurmctldLogFile=$run/log/slurmctld.log
SlurmdLogFile=$run/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
# No cgroups, no accounting, no MPI: nothing a container may lack.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SwitchType=switch/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
# Start queued batch jobs at once (the default, 3 s, starts array tasks in steps of 3 s).
SchedulerParameters=batch_sched_delay=0
ReturnToService=2
# Keep finished jobs in scontrol for 10 minutes, where this script reads their exit codes.
MinJobAge=600
KillWait=5
MailProg=/bin/true
NodeName=$node NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=local Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$conf"   # sbatch, squeue, sinfo, scontrol read this one, not /etc/slurm
echo "node $node: $cpus CPUs, RealMemory=$mem_mb MB; SLURM_CONF=$conf"

# ---------------------------------------------------------------------------------------------
# 3. Start the daemons; stop them (and cancel our jobs) however the script ends
# ---------------------------------------------------------------------------------------------
munged_pid="" ctld_pid="" slurmd_pid=""
jobids=()

show_logs() {   # the tail of each daemon's log (its stderr if it died before opening the log)
    local d f
    for d in munged slurmctld slurmd; do
        f="$run/log/$d.log"
        [ -s "$f" ] || f="$run/log/$d.out"
        [ -s "$f" ] || continue
        echo "---- tail of $f" >&2
        tail -n 25 "$f" >&2
    done
}

stop_pid() {   # stop_pid NAME PID: SIGTERM, up to 10 s, then SIGKILL
    local name="$1" pid="$2" i
    [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null || return 0
    kill -TERM "$pid" 2>/dev/null || true
    for i in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
    if kill -0 "$pid" 2>/dev/null; then
        echo "$name (pid $pid) did not stop on SIGTERM: SIGKILL" >&2
        kill -KILL "$pid" 2>/dev/null || true
    fi
    wait "$pid" 2>/dev/null || true
}

cleanup() {
    local rc=$? i
    trap - EXIT
    if [ ${#jobids[@]} -gt 0 ] && [ -n "$ctld_pid" ] && kill -0 "$ctld_pid" 2>/dev/null; then
        if [ -n "$(squeue -h -j "$(IFS=,; echo "${jobids[*]}")" 2>/dev/null)" ]; then
            echo "cancelling jobs ${jobids[*]}" >&2
            scancel "${jobids[@]}" 2>/dev/null || true
            for i in $(seq 50); do
                [ -z "$(squeue -h -j "$(IFS=,; echo "${jobids[*]}")" 2>/dev/null)" ] && break
                sleep 0.2
            done
        fi
    fi
    stop_pid slurmd "$slurmd_pid"
    stop_pid slurmctld "$ctld_pid"
    stop_pid munged "$munged_pid"
    [ -n "$munged_pid$ctld_pid$slurmd_pid" ] && echo "stopped the daemons this script started"
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM HUP

fail() { echo "FAIL: $*" >&2; exit 1; }
fail_logs() {   # the logs, then the reason and the daemons' last fatal or error lines
    show_logs
    echo "FAIL: $*" >&2
    grep -h -E 'fatal|error' "$run"/log/*.out 2>/dev/null | grep -v -E 'pmix|PMIx|MPI: Cannot|state file|NOTE: Trying' \
        | tail -n 5 | sed 's/^/  /' >&2 || true
    exit 1
}

step "starting munged, slurmctld, slurmd"
# --force: start even if a parent directory of the checkout is group-writable (munged refuses by default).
munged --foreground --force --socket="$sock" --key-file="$run/munge/munge.key" \
    --pid-file="$run/munge/munged.pid" --seed-file="$run/munge/munged.seed" \
    --log-file="$run/log/munged.log" >"$run/log/munged.out" 2>&1 &
munged_pid=$!
for i in $(seq 50); do
    munge -n -S "$sock" 2>/dev/null | unmunge -S "$sock" >/dev/null 2>&1 && break
    kill -0 "$munged_pid" 2>/dev/null || fail_logs "munged exited"
    sleep 0.2
done
munge -n -S "$sock" | unmunge -S "$sock" >/dev/null || fail_logs "munge does not answer on $sock"
echo "munged (pid $munged_pid) answers on $sock"

t_start=$(now)
slurmctld -D -f "$conf" >"$run/log/slurmctld.out" 2>&1 &
ctld_pid=$!
slurmd -D -f "$conf" -N "$node" >"$run/log/slurmd.out" 2>&1 &
slurmd_pid=$!
state=""
for i in $(seq 120); do   # up to 60 s for the node to register and become idle
    kill -0 "$ctld_pid" 2>/dev/null || fail_logs "slurmctld exited"
    kill -0 "$slurmd_pid" 2>/dev/null || fail_logs "slurmd exited"
    state="$(sinfo -h -n "$node" -o %T 2>/dev/null || true)"
    [ "$state" = idle ] && break
    sleep 0.5
done
if [ "$state" != idle ]; then
    sinfo -R >&2 || true
    fail_logs "node $node is '${state:-unknown}', not idle, 60 s after starting slurmctld and slurmd"
fi
t_up=$(now)
echo "slurmctld (pid $ctld_pid) and slurmd (pid $slurmd_pid) up; node $node idle after $(secs "$t_start" "$t_up") s"
sinfo

# ---------------------------------------------------------------------------------------------
# 4. Submit the array and the merge, and wait for them
# ---------------------------------------------------------------------------------------------
job_ok() {   # job_ok JOBID: every task COMPLETED with exit code 0 (scontrol keeps them MinJobAge s)
    scontrol -o show job "$1" | awk '
        { st = ""; ec = ""; id = ""; task = ""
          for (i = 1; i <= NF; i++) {
              if ($i ~ /^JobState=/) st = substr($i, 10)
              if ($i ~ /^ExitCode=/) ec = substr($i, 10)
              if ($i ~ /^JobId=/ && id == "") id = substr($i, 7)
              if ($i ~ /^ArrayJobId=/) id = substr($i, 12)
              if ($i ~ /^ArrayTaskId=/) task = "_" substr($i, 13)
          }
          id = id task
          printf "  job %s: %s, exit code %s\n", id, st, ec
          if (st != "COMPLETED" || ec != "0:0") bad = 1 }
        END { exit bad }'
}

wait_gone() {   # wait_gone JOBID SECONDS: until the job has left the queue
    local jid="$1" limit="$2" t0 left
    t0=$(now)
    while left="$(squeue -h -j "$jid" -o '%i %T %r' 2>/dev/null)" && [ -n "$left" ]; do
        if awk -v a="$t0" -v b="$(now)" -v l="$limit" 'BEGIN { exit !(b - a > l) }'; then
            echo "$left" >&2
            fail_logs "job $jid still queued after $limit s"
        fi
        sleep 0.25
    done
}

export OUT="$run/out"
if [ "$smoke" = 1 ]; then
    # A stand-in for ohd: records its command line in its --out directory. It proves the sbatch
    # scripts hand every task the right --shard, --threads and arguments, without ohd.
    export OHD="$run/fake-ohd"
    cat > "$OHD" <<'EOF'
#!/usr/bin/env bash
set -euo pipefail
out=""; prev=""
for a in "$@"; do [ "$prev" = --out ] && out="$a"; prev="$a"; done
mkdir -p "$out"
printf '%s\n' "$@" > "$out/args"
EOF
    chmod +x "$OHD"
    unset CONFIG
else
    export OHD="$ohd" CONFIG="$config"
fi
args=(--samples "$samples" --seed "$seed")

step "sbatch: array of $shards shards, then the merge"
cd "$run/jobs"   # the jobs start here and write their ohd-*.out logs here
t_submit=$(now)
array_id=$(sbatch --parsable --array=0-$((shards - 1)) "$here/ohd_array.sbatch" "${args[@]}")
jobids+=("$array_id")
merge_id=$(sbatch --parsable --dependency=afterok:"$array_id" "$here/ohd_merge.sbatch")
jobids+=("$merge_id")
echo "array job $array_id (tasks 0-$((shards - 1)), ${args[*]}), merge job $merge_id (afterok:$array_id)"
squeue
wait_gone "$array_id" 600
t_array=$(now)
show_job_logs() { local f; for f in "$run"/jobs/*.out; do echo "---- $(basename "$f")"; cat "$f"; done; }
echo "---- states"
if ! job_ok "$array_id"; then
    # The merge then stays pending on DependencyNeverSatisfied; the exit trap cancels it.
    show_job_logs
    fail "an array task failed (its log above)"
fi
wait_gone "$merge_id" 600
t_merge=$(now)
job_ok "$merge_id" || { show_job_logs; fail "the merge job failed (its log above)"; }
cd "$repo"
show_job_logs
echo "array: $(secs "$t_submit" "$t_array") s from submission to the last task's end;" \
     "merge done $(secs "$t_array" "$t_merge") s later"

# ---------------------------------------------------------------------------------------------
# 5. Compare
# ---------------------------------------------------------------------------------------------
if [ "$smoke" = 1 ]; then
    step "checking what each task was given"
    for i in $(seq 0 $((shards - 1))); do
        want="run --shard $i/$shards --out $OUT/shard_$i -q --threads 1 ${args[*]}"
        got="$(paste -sd' ' "$OUT/shard_$i/args")"
        [ "$got" = "$want" ] || fail "task $i ran '$got', expected '$want'"
    done
    want="merge $(for i in $(seq 0 $((shards - 1))); do printf '%s ' "$OUT/shard_$i"; done | xargs -n1 | sort | xargs) --out $OUT/merged"
    got="$(paste -sd' ' "$OUT/merged/args")"
    [ "$got" = "$want" ] || fail "the merge ran '$got', expected '$want'"
    step "PASS (smoke): Slurm ran $shards array tasks and the dependent merge with the expected command lines"
    echo "  Slurm up in $(secs "$t_start" "$t_up") s, array $(secs "$t_submit" "$t_array") s, merge +$(secs "$t_array" "$t_merge") s"
    exit 0
fi

step "the same run in one piece: ohd run"
t0=$(now)
"$ohd" run "$config" --out "$run/single" -q "${args[@]}"
t_single=$(secs "$t0" "$(now)")
echo "single run: $t_single s on $(nproc) thread(s)"

step "comparing $OUT/merged with $run/single"
merged="$OUT/merged" single="$run/single"
files_m="$(cd "$merged" && find . -type f | sort)"
files_s="$(cd "$single" && find . -type f | sort)"
ok=1
if [ "$files_m" != "$files_s" ]; then
    echo "different file sets:" >&2
    diff <(echo "$files_s") <(echo "$files_m") >&2 || true
    ok=0
fi
n=0
while read -r f; do
    [ "$f" = ./manifest.json ] && continue
    [ -f "$merged/$f" ] || continue
    if cmp -s "$single/$f" "$merged/$f"; then
        n=$((n + 1))
    else
        echo "differs: $f" >&2; ok=0
    fi
done <<< "$files_s"
echo "$n data file(s) identical: $(echo "$files_s" | grep -v '^./manifest.json$' | xargs)"
if diff <(jq -S .estimates "$single/manifest.json") <(jq -S .estimates "$merged/manifest.json") >&2; then
    echo "manifest.json estimates identical:"
    jq -c '.estimates' "$merged/manifest.json" | cut -c1-300
else
    echo "manifest.json estimates differ (above)" >&2; ok=0
fi
# The rest of manifest.json may differ only in timings, threads and the invocation (--threads in
# the overrides and in the configuration as run); everything else must be equal too.
changed="$(jq -rn --slurpfile a "$single/manifest.json" --slurpfile b "$merged/manifest.json" '
    ($a[0] | [paths(type != "object" and type != "array")]) as $pa
    | ($b[0] | [paths(type != "object" and type != "array")]) as $pb
    | ($pa + $pb | unique)[] as $p
    | select(($a[0] | getpath($p)) != ($b[0] | getpath($p)))
    | $p | map(tostring) | join(".")' | paste -sd' ')"
norm='del(.wall_seconds, .threads, .overrides, .config.run.threads,
          .run_statistics.events_per_second, .run_statistics.paths_per_second,
          .run_statistics.speckle_seconds)
      | .config_toml |= (split("\n") | map(select(test("^threads *=") | not)) | join("\n"))'
if diff <(jq -S "$norm" "$single/manifest.json") <(jq -S "$norm" "$merged/manifest.json") >&2; then
    echo "manifest.json otherwise differs only in: ${changed:-nothing}"
else
    echo "manifest.json differs beyond timings, threads and invocation (above); all differing keys: $changed" >&2
    ok=0
fi

t_total=$(secs "$t_submit" "$t_merge")
if [ "$ok" = 1 ]; then
    step "PASS: $shards Slurm array shards + merge == one ohd run (byte for byte)"
else
    step "FAIL: the merged shards differ from the single run"
fi
echo "  experiment $(basename "$config"), ${args[*]}, $shards shards on $cpus CPU(s), 1 thread each"
echo "  Slurm: array $(secs "$t_submit" "$t_array") s + merge $(secs "$t_array" "$t_merge") s = $t_total s wall; single ohd run $t_single s"
[ "$ok" = 1 ]

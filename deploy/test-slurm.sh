#!/usr/bin/env bash
# Kiln's workers through Slurm for real: installs Debian's slurm-wlm and munge if missing,
# starts munged, slurmctld and slurmd as a one-node cluster on this machine (its own config
# under a temporary folder), runs a coordinator on loopback, submits a scene, starts the
# workers with deploy/slurm/kiln-workers.sbatch as a job array, scancels one array task
# mid-job, and checks the frame against `kiln render` byte for byte.
#
#   deploy/test-slurm.sh        (prints SKIPPED without root or where Slurm cannot be installed)
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "$(id -u)" != 0 ]; then
    echo "test-slurm: SKIPPED: starting slurmctld and slurmd needs root"
    exit 0
fi
if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge) >/dev/null 2>&1 || true
fi
if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
    echo "test-slurm: SKIPPED: slurm-wlm and munge could not be installed"
    exit 0
fi
NAME=test-slurm
. deploy/lib.sh
work="$(mktemp -d)"
chmod 755 "$work"
pids=()
cleanup() {
    scancel --user=root >/dev/null 2>&1 || true
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
    pkill -f "slurmctld -f $work" 2>/dev/null || true
    pkill -f "slurmd -f $work" 2>/dev/null || true
    [ -n "${started_munge:-}" ] && pkill -x munged 2>/dev/null || true
    wait 2>/dev/null || true
    # slurmctld and slurmd are daemons, not this shell's children: `wait` does not
    # wait for them, and slurmctld writes its state files into $work/ctld as it shuts
    # down. Removing the folder under it raced ("Directory not empty") and failed a
    # passed test; wait for them to be gone first, and never let tidying fail the run.
    for _ in $(seq 50); do
        pgrep -f -- "slurm(ctld|d) -f $work" >/dev/null 2>&1 || break
        sleep 0.2
    done
    pkill -KILL -f -- "slurm(ctld|d) -f $work" 2>/dev/null || true
    if [ -n "${KEEP:-}" ]; then
        echo "test-slurm: kept $work"
    else
        rm -rf "$work" 2>/dev/null || { sleep 1; rm -rf "$work" 2>/dev/null; } ||
            echo "test-slurm: could not remove $work (left behind)"
    fi
}
trap cleanup EXIT

cargo build --release --locked --bin kiln >/dev/null 2>&1
kiln="$(pwd)/target/release/kiln"
host=$(hostname)
cpus=$(nproc)

step "munge, slurmctld and slurmd: a one-node cluster ($host, $cpus CPUs)"
if [ ! -s /etc/munge/munge.key ]; then
    dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 2>/dev/null
    chmod 400 /etc/munge/munge.key
fi
chown munge:munge /etc/munge/munge.key 2>/dev/null || true
mkdir -p /run/munge && chown munge:munge /run/munge 2>/dev/null || true
if ! pgrep -x munged >/dev/null; then
    su -s /bin/sh munge -c munged 2>/dev/null || munged --force
    started_munge=1
fi
mkdir -p "$work/ctld" "$work/d" "$work/logs"
cat > "$work/slurm.conf" <<CONF
ClusterName=kiln-ci
SlurmctldHost=$host
SlurmctldPort=$(( 16817 + $$ % 1000 ))
SlurmdPort=$(( 17817 + $$ % 1000 ))
AuthType=auth/munge
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$work/ctld
SlurmdSpoolDir=$work/d
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/logs/slurmctld.log
SlurmdLogFile=$work/logs/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
ReturnToService=2
MpiDefault=none
NodeName=$host CPUs=$cpus State=UNKNOWN
PartitionName=main Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$work/slurm.conf"
slurmctld -f "$work/slurm.conf" -i
slurmd -f "$work/slurm.conf"
must_wait 30 'sinfo -h -o %T 2>/dev/null | grep -qE "idle|mixed"' "slurmd to register"
step "sinfo: $(sinfo -h -o '%P %D %T %C')"

export KILN_TOKEN="slurm-$$"
port=$(( 21000 + $$ % 20000 ))
url="http://127.0.0.1:$port"
"$kiln" coordinator --listen "127.0.0.1:$port" --data-dir "$work/data" --lease-ttl 3 > "$work/coord.log" 2>&1 &
pids+=($!)
must_wait 30 '"$kiln" health --coordinator "$url" --timeout 1 >/dev/null 2>&1' "the coordinator's health check"
scene=scenes/molten-glass/scene.pbrt
args=(--spp 128 --resolution 360x240 --tile 32)
id=$("$kiln" submit "$scene" --coordinator "$url" "${args[@]}" | sed 's/.*job //')
step "job $id submitted to the coordinator at $url (${args[*]})"
array=$(cd "$work" && KILN="$kiln" KILN_COORDINATOR="$url" sbatch --parsable --array=0-2 --cpus-per-task=1 "$OLDPWD/deploy/slurm/kiln-workers.sbatch")
step "sbatch: array job $array (3 tasks of 1 CPU on $cpus CPUs: one waits)"
queue() { squeue -h -j "$array" -o '%i %T' | tr '\n' ' '; }
wait_until 120 '[ "$(field tiles_done)" -ge 6 ]' || { echo "test-slurm: FAILED: no tiles came back; squeue: $(squeue -h -o '%i %T %r')"; cat "$work"/kiln-worker-*.log 2>/dev/null | tail -5; tail -5 "$work/logs/slurmd.log"; exit 1; }
step "tiles done $(field tiles_done)/$(field tiles_total); squeue: $(queue)"
step "scancel ${array}_0 (SIGTERM: the worker delivers the tile in hand and leaves)"
scancel "${array}_0"
must_wait 90 'squeue -h -j "${array}_2" -o %T | grep -q RUNNING' "task 2 to start"
step "task 2 took its place; squeue: $(queue); tiles done $(field tiles_done)"
sleep 3
# (scancel --signal=KILL is a cancel, which sends SIGTERM first: the worker would deliver its
# tile. A crash is a SIGKILL to the worker itself, as a node that dies gives.)
step "SIGKILL to task ${array}_1's worker mid-tile, as a crashed node (its lease must expire and the tile be lent again)"
pkill -KILL -f -- "--name slurm-${array}-1 "
wait_until 60 '[ "$(metric kiln_leases_expired_total)" -ge 1 ]' || { echo "test-slurm: no lease expired; squeue: $(queue)"; tail -3 "$work"/kiln-worker-${array}_1.log; grep -i kill "$work/logs/slurmd.log" | tail -3; exit 1; }
step "leases issued $(metric kiln_leases_issued_total), expired $(metric kiln_leases_expired_total); tiles done $(field tiles_done); squeue: $(queue)"
"$kiln" submit "$scene" --coordinator "$url" "${args[@]}" --wait --quiet -o "$work/farm.exr" >/dev/null 2>&1
step "job $id done: tiles $(field tiles_done)/$(field tiles_total), tiles accepted $(metric kiln_tiles_accepted_total)"
scancel "$array"
"$kiln" render "$scene" "${args[@]}" --quiet -o "$work/direct.exr" 2>/dev/null
if ! cmp -s "$work/farm.exr" "$work/direct.exr"; then
    echo "test-slurm: FAILED: the farm's frame differs from kiln render's"
    exit 1
fi
step "the workers' logs: $(cat "$work"/kiln-worker-*.log 2>/dev/null | grep -c 'tile' || true) lines about tiles"
step "the same bytes as kiln render: passed"

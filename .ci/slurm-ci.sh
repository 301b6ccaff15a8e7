#!/usr/bin/env bash
# Throwaway single-node Slurm cluster on localhost for CI.
# Debian 12 (bookworm), run as root, no systemd needed. Everything (munge key,
# munge socket, slurm.conf, state, logs) lives under $SLURM_CI_DIR; nothing is
# written to /etc, /run or /var except by apt-get itself.
#
#   bash setup.sh start          install (if needed) + start munged, slurmctld, slurmd;
#                                waits until the node is idle
#   export SLURM_CONF=$SLURM_CI_DIR/slurm.conf   # every sbatch/srun/squeue needs this
#   bash setup.sh wait JOBID [TIMEOUT_S]         # poll until JOBID (incl. all array
#                                tasks) has left the queue; exit 1 unless every task
#                                COMPLETED with ExitCode=0:0
#   bash setup.sh stop           stop the three daemons, delete $SLURM_CI_DIR
#   bash setup.sh demo           start + sbatch --array=0-1 + srun hostname + stop
#
# Env: SLURM_CI_DIR (default /tmp/slurm-ci), SLURM_CI_PORT (slurmctld port,
# default 6817; slurmd uses PORT+1).
set -euo pipefail

DIR=${SLURM_CI_DIR:-/tmp/slurm-ci}
PORT=${SLURM_CI_PORT:-6817}
export SLURM_CONF=$DIR/slurm.conf

log() { echo "[slurm-ci] $*" >&2; }

install_pkgs() {
    if command -v slurmctld >/dev/null && command -v slurmd >/dev/null &&
       command -v sbatch >/dev/null && command -v munged >/dev/null; then
        return
    fi
    log "installing slurmctld slurmd slurm-client munge"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends \
        slurmctld slurmd slurm-client munge >/dev/null
}

start() {
    install_pkgs
    if [ -e "$DIR" ]; then
        log "$DIR exists: stopping a previous instance first"
        stop
    fi
    mkdir -p "$DIR"/{munge,ctld,spool,log}
    # munged refuses a socket dir without o+x ("Socket is inaccessible:
    # execute permissions for all required"); the key itself must be 0600.
    chmod 755 "$DIR" "$DIR/munge"
    mungekey --create --keyfile="$DIR/munge/munge.key"
    chmod 600 "$DIR/munge/munge.key"
    munged --socket="$DIR/munge/munge.sock" \
           --key-file="$DIR/munge/munge.key" \
           --pid-file="$DIR/munge/munged.pid" \
           --seed-file="$DIR/munge/munged.seed" \
           --log-file="$DIR/log/munged.log"
    munge -S "$DIR/munge/munge.sock" -n | unmunge -S "$DIR/munge/munge.sock" >/dev/null

    local host node
    host=$(hostname -s)
    # e.g. "NodeName=vm CPUs=2 Boards=1 SocketsPerBoard=1 CoresPerSocket=2 ThreadsPerCore=1 RealMemory=24105"
    node=$(slurmd -C | head -n1)
    cat > "$SLURM_CONF" <<EOF
ClusterName=ci
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$PORT
SlurmdPort=$((PORT + 1))
SlurmUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$DIR/munge/munge.sock
MailProg=/bin/true
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
# default batch_sched_delay=3 makes array tasks wait up to 3 s for the scheduler tick
SchedulerParameters=batch_sched_delay=0
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
StateSaveLocation=$DIR/ctld
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/slurmctld.pid
SlurmdPidFile=$DIR/slurmd.pid
SlurmctldLogFile=$DIR/log/slurmctld.log
SlurmdLogFile=$DIR/log/slurmd.log
$node NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=ci Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
    slurmctld -i       # -i: ignore (absent) saved state; daemonizes
    slurmd             # daemonizes
    local i state=""
    for i in $(seq 1 120); do   # up to 30 s; takes ~0.3 s here
        state=$(sinfo -h -o %T 2>/dev/null || true)
        [ "$state" = idle ] && { log "node $host idle; SLURM_CONF=$SLURM_CONF"; return 0; }
        sleep 0.25
    done
    log "node never became idle (state '$state'); logs follow"
    tail -n 30 "$DIR"/log/*.log >&2 || true
    return 1
}

stop_pidfile() {   # stop_pidfile FILE NAME
    local f=$1 name=$2 pid i
    [ -s "$f" ] || return 0
    pid=$(cat "$f")
    # only signal it if it is still the daemon we started
    if [ "$(cat /proc/"$pid"/comm 2>/dev/null)" = "$name" ]; then
        kill "$pid" 2>/dev/null || true
        for i in $(seq 1 100); do
            [ -d /proc/"$pid" ] && [ "$(cut -d' ' -f3 /proc/"$pid"/stat 2>/dev/null)" != Z ] || return 0
            sleep 0.1
        done
        log "$name ($pid) did not exit after 10 s, sending SIGKILL"
        kill -9 "$pid" 2>/dev/null || true
    fi
}

stop() {
    [ -d "$DIR" ] || return 0
    stop_pidfile "$DIR/slurmd.pid" slurmd
    stop_pidfile "$DIR/slurmctld.pid" slurmctld
    stop_pidfile "$DIR/munge/munged.pid" munged
    rm -rf "$DIR"
}

wait_job() {   # wait_job JOBID [TIMEOUT_S]
    local jid=$1 timeout=${2:-300} t0=$SECONDS
    # (sbatch --wait also works, but polls at 2 s, 10 s, 42 s, 74 s, ... after submission)
    while [ -n "$(squeue -h -j "$jid" 2>/dev/null)" ]; do
        if [ $((SECONDS - t0)) -ge "$timeout" ]; then
            log "job $jid still queued/running after ${timeout}s"; scancel "$jid" || true; return 1
        fi
        sleep 0.2
    done
    # records stay for MinJobAge (300 s default) after completion
    local info
    info=$(scontrol -o show job "$jid")
    echo "$info" | grep -o 'JobId=[0-9]* ArrayJobId=[0-9]* ArrayTaskId=[0-9]*\|JobState=[A-Z_]*\|ExitCode=[0-9:]*' |
        paste -d' ' - - - >&2
    if echo "$info" | grep -v 'JobState=COMPLETED .*ExitCode=0:0' | grep -q .; then
        log "job $jid: some task did not complete with exit 0"; return 1
    fi
}

demo() {
    local t0=$SECONDS
    start
    trap stop EXIT
    local work=$DIR/demo jid
    mkdir -p "$work"
    cat > "$work/task.sh" <<'EOF'
#!/bin/bash
# a real test would run: pma-exo sweep FILE.toml --out DIR --shard $((SLURM_ARRAY_TASK_ID+1))/2
echo "$SLURM_ARRAY_TASK_ID" > "$OUT/task-$SLURM_ARRAY_TASK_ID.txt"
EOF
    jid=$(OUT=$work sbatch --parsable --array=0-1 -o "$work/slurm-%A_%a.out" "$work/task.sh")
    wait_job "$jid" 60
    [ "$(cat "$work/task-0.txt")" = 0 ] && [ "$(cat "$work/task-1.txt")" = 1 ]
    log "array job $jid: both tasks ran"
    [ "$(srun hostname)" = "$(hostname)" ]
    log "srun hostname ok; total $((SECONDS - t0))s"
}

case "${1:-}" in
    start) start ;;
    stop) stop ;;
    wait) shift; wait_job "$@" ;;
    demo) demo ;;
    *) echo "usage: $0 start|stop|wait JOBID [TIMEOUT]|demo" >&2; exit 2 ;;
esac

# Sourced by the gait pipelines (agent-gait.sh, agent-gait-ground.sh): run commands together, pass one
# SIGTERM (or Ctrl-C) on to them, which checkpoint, and stop.

running=()
stop() {
  trap - TERM INT
  if [ ${#running[@]} -gt 0 ]; then kill -TERM "${running[@]}" 2>/dev/null || true; fi
  wait
  exit 130
}
trap stop TERM INT

# Run each argument (a command line) at once and wait for all; the first failure stops the others.
together() {
  running=()
  for command in "$@"; do
    echo "$(date -u +%FT%TZ) $command"
    bash -c "exec $command" &
    running+=($!)
  done
  for pid in "${running[@]}"; do
    if ! wait "$pid"; then
      kill -TERM "${running[@]}" 2>/dev/null || true
      wait
      exit 1
    fi
  done
  running=()
}

# Sourced by the pipelines under examples/ (gait, robust, perceptive): run commands together, pass one
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

# Copy each run folder in $1 (a session's committed, unfinished runs) not yet in $2 there, except one named
# $3 (the seed group of the agent being built, restored on its own), so a run goes on where it stopped.
restore() {
  [ -d "$1" ] || return 0
  for folder in "$1"/*/; do
    name=$(basename "$folder")
    if [ "$name" != "${3:-}" ] && [ ! -e "$2/$name" ]; then mkdir -p "$2" && cp -r "$folder" "$2/$name"; fi
  done
}

# Sourced by bootstrap.sh and sanitize.sh: `stage NAME command...` runs the command, prints its wall
# time, and adds it to the summary `stage_summary` prints (the file LBLIGHT_STAGE_LOG collects the
# stages of nested scripts).
export LBLIGHT_STAGE_LOG="${LBLIGHT_STAGE_LOG:-$(mktemp -t lblight-stages.XXXXXX)}"
stage() {
  local name="$1" start end rc=0
  shift
  start=$(date +%s)
  echo "=== stage $name: $*"
  "$@" || rc=$?
  end=$(date +%s)
  echo "=== stage $name: $((end - start)) s (exit $rc)"
  echo "$name $((end - start))" >>"$LBLIGHT_STAGE_LOG"
  return "$rc"
}
stage_summary() {
  local total=0
  echo "=== stage times (s):"
  while read -r name secs; do
    printf '===   %-18s %5d\n' "$name" "$secs"
    total=$((total + secs))
  done <"$LBLIGHT_STAGE_LOG"
  printf '===   %-18s %5d (%d min %d s)\n' total "$total" $((total / 60)) $((total % 60))
  rm -f "$LBLIGHT_STAGE_LOG"
}

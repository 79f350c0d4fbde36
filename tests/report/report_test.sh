#!/bin/sh
# The HTML report in a headless browser: simulate the drill for a while, write its report, load
# the page in Debian's Chromium (no network, file://). Passes when the page reports itself ready
# (its video decoded), the browser logged no console message at all, and a screenshot of the
# page is not blank.
# usage: report_test.sh CROWDMPM CHROMIUM CHECK_SCREENSHOT SCENARIO WORK_DIR
set -eu
CLI=$1 CHROMIUM=$2 CHECK=$3 SCENARIO=$4 WORK=$5
rm -rf "$WORK"
mkdir -p "$WORK"
"$CLI" simulate "$SCENARIO" --out "$WORK/run" --duration 20 --quiet
"$CLI" report "$WORK/run"
page="file://$WORK/run/report.html"
browser() {
  timeout 120 "$CHROMIUM" --headless=new --no-sandbox --disable-gpu --no-first-run --user-data-dir="$WORK/profile" \
    --enable-logging=stderr --v=0 --virtual-time-budget=15000 "$@"
}
browser --dump-dom "$page" > "$WORK/dom.html" 2> "$WORK/browser.log"
if grep -q ":CONSOLE" "$WORK/browser.log"; then
  echo "the page logged to the console:"
  grep ":CONSOLE" "$WORK/browser.log"
  exit 1
fi
grep -q 'data-report="ready"' "$WORK/dom.html" || {
  echo "the page did not report ready (its video did not load?): $(grep -o '<body[^>]*>' "$WORK/dom.html")"
  exit 1
}
for part in 'id="summary"' '<svg' 'data:image/png;base64' 'data:video/webm;base64' 'Fruin level'; do
  grep -q "$part" "$WORK/dom.html" || { echo "the page lacks $part"; exit 1; }
done
browser --hide-scrollbars --window-size=1400,2400 --screenshot="$WORK/report.png" "$page" 2>> "$WORK/browser.log" > /dev/null
"$CHECK" "$WORK/report.png" 1400 2400
echo "report loads in $CHROMIUM with no console message; screenshot $WORK/report.png"

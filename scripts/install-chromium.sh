#!/bin/sh
# Debian's Chromium, for the test that opens report.html in a real (headless) browser.
exec sh "$(dirname "$0")/apt-install.sh" "command -v chromium" "the report's browser test will be skipped" chromium

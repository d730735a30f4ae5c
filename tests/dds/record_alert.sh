#!/bin/sh
# `dronetrack alert --exec` target for the multi-process test: appends its arguments, one alert
# per line, to $DRONETRACK_ALERT_LOG.
echo "$@" >> "$DRONETRACK_ALERT_LOG"

"""The autopilot's own logs in: an ArduPilot DataFlash log (``.bin``) or a MAVLink telemetry log
(``.tlog``) read with pymavlink, each landing in it found, and the landing compared with the
model run at its conditions on what the log can see (docs/flight-logs.md).

One module per step: :mod:`.reader` (the file to time series in SI units, whichever kind it is),
:mod:`.landings` (where the landings are: the script's states, the motor outputs, first contact
from the accelerometer), :mod:`.conditions` (the landing's conditions from the log, each with
where it came from), :mod:`.observe` (the model seen through the autopilot's sensors and
filters), :mod:`.compare` (log against model: the table, the JSON, the plot).
"""

"""The live motion simulator: vehicle telemetry over UDP -> the causal washout -> the safety
envelope -> leg setpoints to the device over MAVLink (`stewart-sim cue-live`), and the recorded
motion streamed as telemetry (`stewart-sim telemetry-replay`)."""

"""Calibration against measured tracks: data -> residuals -> candidate effects -> fit -> report.

``data`` reads the interchange format (CSV + JSON sidecar); ``sim`` replays
measured trials in the model; ``residuals`` turns measured and simulated
tracks into the statistics a physicist reads; ``effects`` is the library of
model extensions; ``fit`` diagnoses and fits them, ``stages`` runs the loop and selects them; ``report``
writes the verdict; ``armoffset`` reads an arm resting off its commanded corners before any fit;
``synth`` makes measured-like data with hidden effects; ``independent`` is a
second smarticle simulator, written apart from the library (it imports none of it), whose data the
tests and benchmarks calibrate against.
"""

"""Calibration against measured tracks: data -> residuals -> candidate effects -> fit -> report.

``data`` reads the interchange format (CSV + JSON sidecar); ``sim`` replays
measured trials in the model; ``residuals`` turns measured and simulated
tracks into the statistics a physicist reads; ``effects`` is the library of
model extensions; ``fit`` diagnoses, fits and selects them; ``report``
writes the verdict; ``synth`` makes measured-like data with hidden effects.
"""

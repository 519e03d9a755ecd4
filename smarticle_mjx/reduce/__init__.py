"""Reducers: stores -> physical quantities. numpy and h5py only, no engine."""

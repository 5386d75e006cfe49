"""Bring-up of the MR damper suite: launch file, configs, launcher, recorder, report and plots."""

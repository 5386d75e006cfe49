"""mr_damper_rig: see README.md."""

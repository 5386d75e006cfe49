"""mr_damper_model: see README.md."""

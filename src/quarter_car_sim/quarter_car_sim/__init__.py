"""quarter_car_sim: see README.md."""

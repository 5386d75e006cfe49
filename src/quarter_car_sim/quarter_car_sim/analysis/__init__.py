"""Plots of the linear car's responses and of ride studies (matplotlib, loaded on first use)."""

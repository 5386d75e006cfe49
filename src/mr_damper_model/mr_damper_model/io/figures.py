"""
Writing a matplotlib figure to a file (the one home of it for the tools and the batch trend).

matplotlib loads when a figure is saved, not when this module is imported.
"""


def save_figure(fig, path):
    """Save a figure (format from the file suffix) at 110 dpi and close it."""
    import matplotlib.pyplot as plt        # lazy: importing io must not load matplotlib
    try:
        fig.savefig(path, dpi=110)
    finally:
        plt.close(fig)

"""Command-line tools: ``mr-damper-identify`` (``cli``; ``--batch``: ``batch_cli``) and plots."""

"""Scripts of the repository that are not packages (``bench/``, ``launch_scripts/``) as modules."""
import importlib.util
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def load_script(relative):
    """Return the script at ``relative`` (to the repository root) imported as a module."""
    path = REPO / relative
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module

"""robofdi: model-based fault detection, isolation, identification and fault-tolerant control of robots."""
from importlib import resources
from pathlib import Path

__version__ = "0.1.0"
__all__ = ["ASSETS", "RobofdiError", "__version__", "assets_dir"]


def assets_dir() -> Path:
    """Folder of the shipped MJCF models: the package data of ``robofdi.assets`` (the repository's ``assets/``).

    Read through ``importlib.resources``; robofdi is installed as plain files (wheel or ``pip install -e .``), so
    this is a real folder that MuJoCo and Pinocchio can open by path.
    """
    try:
        folder = resources.files("robofdi.assets")
    except ModuleNotFoundError:
        # A source checkout on PYTHONPATH without an install: robofdi.assets is only mapped by the packaging.
        folder = Path(__file__).resolve().parents[1] / "assets"
        if not (folder / "__init__.py").is_file():
            raise
    if not isinstance(folder, Path):
        raise RuntimeError(f"robofdi.assets is not a folder on the file system ({folder!r}); install robofdi unzipped")
    return folder


#: Folder of the shipped MJCF models (same as :func:`assets_dir`, kept for compatibility).
ASSETS = assets_dir()


from robofdi.errors import RobofdiError  # noqa: E402

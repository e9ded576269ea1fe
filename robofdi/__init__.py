"""robofdi: model-based fault detection, isolation, identification and fault-tolerant control of robots."""
from pathlib import Path

__version__ = "0.1.0"

#: Folder of the shipped MJCF models (the repository's ``assets/``).
ASSETS = Path(__file__).resolve().parents[1] / "assets"


from robofdi.errors import RobofdiError  # noqa: E402

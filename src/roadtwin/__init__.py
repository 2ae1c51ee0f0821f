"""roadtwin: georeferenced ASAM OpenDRIVE digital twins of highways.

Fuses a mobile-mapping run (poses, road-edge points, lane-marking samples) with the
OpenStreetMap road graph into one connected OpenDRIVE map.
"""

from __future__ import annotations

import logging

__version__ = "0.1.0"

logging.getLogger(__name__).addHandler(logging.NullHandler())

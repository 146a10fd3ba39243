"""The mechanism in 3-D in a browser (viser): a live viewer, or a self-contained HTML page.

```python
from scdk_sym import view

view.write_html(model, res, "solve.html")  # a SolveResult's path, a TrackResult, a Configuration
view.show(model, cfg, port=8080)           # serves until Ctrl-C
```

Every link's URDF visual (else collision) geometry is drawn where the URDF has some; links
without are segments between their joint origins (blue), closure links (the cut loop pairs)
are green (distance closures as segments, the cut points of the others as dots), the platform
is a filled red-pink outline. viser is optional: ``pip install "scdk_sym[view]"``.
"""

from __future__ import annotations

from ..errors import ViewError
from .render import INSTALL_HINT, Viewer, require_viser, show, write_html
from .scene import COLORS, Body, Frame, RobotScene, Shape, configurations, frame, robot_scene

__all__ = [
    "COLORS",
    "INSTALL_HINT",
    "Body",
    "Frame",
    "RobotScene",
    "Shape",
    "ViewError",
    "Viewer",
    "configurations",
    "frame",
    "require_viser",
    "robot_scene",
    "show",
    "write_html",
]

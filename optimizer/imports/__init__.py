"""``footopt import``: the leg above the ankle from a robot description (URDF or MJCF) as a model
file. ``description`` holds the format-neutral links and joints, ``urdf`` and ``mjcf`` read them,
``leg`` maps a chain of them onto footopt's rods."""

"""Example model files and studies, shipped with the package (``footopt init`` copies the
starters; the repository's ``configs/`` is a link to this folder)."""

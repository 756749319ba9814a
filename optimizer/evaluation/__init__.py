"""Running one model file through the model a scene needs."""

"""The scene renderer: the bench drawn as the camera sees it, for tests and the synthetic
camera, with the truth of every frame."""

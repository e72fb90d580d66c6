"""The synthetic camera's picture of the bench, with the truth of every frame: the scene
description (``scene``), its rasteriser (``render``) and the camera's placement relative
to the beam plane (``pose``). Used by the synthetic bench and the tests."""

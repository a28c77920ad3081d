"""The physics: parameters, rotations, the models, steady motions and scenes (pure)."""

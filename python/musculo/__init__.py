"""musculo: musculoskeletal dynamics for motion datasets, on numpy arrays.

Every array argument may have any leading batch shape; its last axis holds one frame (n values
for q, q̇, q̈, τ; m for muscle activations; P × 3 for contact forces). Work runs in Rust with the
GIL released, frames in parallel. Bad input raises :class:`MusculoError` (a ``ValueError``)
with the library's message.

>>> import musculo, numpy as np
>>> model = musculo.Model.default()
>>> q = model.default_q()
>>> model.mass_matrix(q).shape == (model.nq, model.nq)
True
"""

from ._musculo import (
    EulerLagrangeLoss,
    LayoutEulerLagrangeLoss,
    Model,
    MuscleLoss,
    MusculoError,
    __version__,
    augment_clip,
    augment_file,
    evaluate,
    read_motion,
)

__all__ = [
    "Model",
    "EulerLagrangeLoss",
    "LayoutEulerLagrangeLoss",
    "MuscleLoss",
    "MusculoError",
    "augment_clip",
    "augment_file",
    "evaluate",
    "read_motion",
    "__version__",
]

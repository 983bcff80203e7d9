"""Identification from experiments: step-response models (Andersson 2000, section 2),
black-box models from PRBS data (Nunes 1998, section 3) and their validation.

Every identified SISO element converts to a :class:`~quadtank_tui.core.delaytf.DelayTF`
(its ``tf()``), the model type PI/PID design consumes.  Pure numbers: arrays in,
models out; reading logs and writing model files live in ``files/``.
"""


class IdentificationError(ValueError):
    """Data that cannot be identified from (no step, constant input, too few rows);
    the message says what is wrong in one line."""

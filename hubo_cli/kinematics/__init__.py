"""HUBO 2+ kinematics: DH forward kinematics and the paper's closed-form IK, scalar and batched.

Start with :func:`get_limb` (or :class:`Limb`): ``fk``, ``fk_batch``, ``candidates``, ``solve``,
``solve_batch``. Frames: the neck frame N (x forward, y left, z up); right limbs at -y.
"""

from hubo_cli.kinematics.limb import BatchIKResult, Candidate, IKResult, Limb, get_limb

__all__ = ["BatchIKResult", "Candidate", "IKResult", "Limb", "get_limb"]

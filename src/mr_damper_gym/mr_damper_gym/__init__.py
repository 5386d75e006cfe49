"""
mr_damper_gym: Gymnasium environments for learning semi-active suspension control.

Importing the package registers (gymnasium 1.x has no plugin entry points, so an import, or
gymnasium's ``'mr_damper_gym:<id>'`` form, is needed):

- ``mr_damper/SemiActiveQuarterCar-v0``: :class:`~mr_damper_gym.envs.SemiActiveQuarterCarEnv`;
- ``mr_damper/SemiActiveFullCar-v0``: :class:`~mr_damper_gym.envs.SemiActiveFullCarEnv`;

each with a vector form (``gymnasium.make_vec(id, num_envs=N)``: N cars stepped together by
the compiled step, :class:`~mr_damper_gym.vector.SemiActiveVectorEnv`). Baseline laws as
policies: :mod:`mr_damper_gym.baselines`. Reference: docs/gym.md.
"""
import gymnasium

from mr_damper_gym.core import ActionError, EnvCore, gap_closed
from mr_damper_gym.envs import SemiActiveEnv, SemiActiveFullCarEnv, SemiActiveQuarterCarEnv
from mr_damper_gym.vector import SemiActiveVectorEnv

QUARTER_CAR_ID = 'mr_damper/SemiActiveQuarterCar-v0'
FULL_CAR_ID = 'mr_damper/SemiActiveFullCar-v0'

__all__ = ['ActionError', 'EnvCore', 'FULL_CAR_ID', 'QUARTER_CAR_ID', 'SemiActiveEnv',
           'SemiActiveFullCarEnv', 'SemiActiveQuarterCarEnv', 'SemiActiveVectorEnv',
           'gap_closed']


def _register():
    for env_id, cls, car in ((QUARTER_CAR_ID, 'SemiActiveQuarterCarEnv', 'quarter'),
                             (FULL_CAR_ID, 'SemiActiveFullCarEnv', 'full')):
        if env_id in gymnasium.registry:
            continue
        gymnasium.register(id=env_id, entry_point=f'mr_damper_gym.envs:{cls}',
                           vector_entry_point=f'mr_damper_gym.vector:{cls.replace("Env", "")}'
                                              'VectorEnv',
                           kwargs={}, disable_env_checker=False)


_register()

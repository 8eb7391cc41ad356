"""Which module steps each kind of dynamics and which computes each kind of features, by the type of the value
compiled code is given. Every dynamics module has the same three functions, ``reset(env, rng) -> state``,
``step(env, state, action, rng) -> (state, reward, terminated)`` and ``observe(env, state) -> observation``; every
features module has ``n_active(features)`` and ``activate(features, observation, actives, row)``.
"""

from __future__ import annotations

from rlcompare.envs import acrobot, cartpole, discretize, features, gymnasium_env, mountain_car, table, tiles

DYNAMICS = {
    mountain_car.MountainCar: mountain_car,
    cartpole.CartPole: cartpole,
    acrobot.Acrobot: acrobot,
    table.TableEnv: table,
    gymnasium_env.Adapted: gymnasium_env,
}
FEATURES = {discretize.UniformGrid: discretize, tiles.TileCoding: tiles, features.OneHot: features}

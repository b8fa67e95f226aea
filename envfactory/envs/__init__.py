"""The gymnasium envs and the parts they own: action translation, goal sampling, term managers, object
tracking. Generic: everything robot- or task-specific arrives compiled in the blueprint."""

from envfactory.envs.robot_env import GoalRobotEnv, RobotEnv

__all__ = ["GoalRobotEnv", "RobotEnv"]

"""The low-level planner: follow a goal path with the discrete actions of the task (paper Sec. IV).

Between reasoning events DRIVE-Nav's low-level planner follows the farthest frontier point of the selected
direction (Sec. IV overview and IV-A c), and after a grounding a point near the target, along a path on the
navigable map that is re-planned every step. The path is one of :attr:`DirectionResult.goal_paths`, taken
from the directions pipeline's single weighted-FMM solve, so no second solve is needed here. The planner turns
it into MOVE_FORWARD / TURN_LEFT / TURN_RIGHT:

* Pursuit: the carrot is the first crossing of the path with a circle of radius ``lookahead`` around the
  robot, walking the path on from its vertex nearest the robot (the path's end when the rest lies inside;
  so a path planned from a slightly older pose still works). While the heading error to the carrot exceeds half
  the turn angle the robot turns toward it (left = counter-clockwise = +yaw), so a turn never leaves a larger
  error than the one it corrects; otherwise it steps forward.
* Collision recovery: a forward step reported as collided that moved the robot less than half a step starts
  an escape -- ``escape_turns`` turns toward the side the path bends to, then one forward step. The side is
  kept while collisions continue, and each further collision in a row turns ``escape_turns`` more (up to half a
  circle), so the same blocked move is never repeated. A clean forward step of the pursuit ends the streak.
* Failure: :meth:`LocalPlanner.act` returns ``None`` (and says why in :attr:`LocalPlanner.failure`) when there
  is no usable path, when the path ends within half a step of the robot, when the last ``stuck_steps``
  forward steps it issued moved the robot less than ``stuck_progress`` metres net, or when it would turn more
  than ``max_turns`` times in a row. The caller then re-selects the direction or gives up the target. Stuck
  and spinning reports also clear the planner's history, so each report rests on fresh evidence.

The pose is the robot's pose in the episode frame (the map frame of the path). Only the planner's own
forward steps count as moves; the caller may interleave other actions (e.g. inspection turns), and should
call :meth:`LocalPlanner.reset` whenever it switches to a new goal.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from drivenav.agent.config import PlannerConfig
from drivenav.directions.bearings import circle_crossing
from drivenav.grid import wrap_angle
from drivenav.types import Action, Pose, SimConfig

OWN_CELL = 0.1  # metres of a sight line ignored next to the robot (its own cell may lie in the inflation band)
FreeSpace = Callable[[float, float], bool]
"""Whether a world point (episode frame) is free space on the robot's map."""

Polyline = NDArray[np.float64]  # (N, 2) world (x, y), from the robot to the goal


def reached(path: Polyline | None, pose: Pose, tolerance: float) -> bool:
    """Whether the robot stands within ``tolerance`` metres of the end of ``path``."""
    if path is None or len(path) == 0:
        return False
    return math.hypot(float(path[-1, 0]) - pose.x, float(path[-1, 1]) - pose.y) <= tolerance


def heading_error(pose: Pose, point: tuple[float, float]) -> float:
    """Signed angle in ``(-pi, pi]`` from the robot's heading to ``point`` (positive = to the left)."""
    return wrap_angle(math.atan2(point[1] - pose.y, point[0] - pose.x) - pose.yaw)


class LocalPlanner:
    """Path follower with collision recovery and stuck detection (see the module docstring)."""

    def __init__(
        self,
        sim: SimConfig,
        lookahead: float = PlannerConfig.lookahead,
        stuck_steps: int = PlannerConfig.stuck_steps,
        stuck_progress: float = PlannerConfig.stuck_progress,
        escape_turns: int = PlannerConfig.escape_turns,
        max_turns: int = PlannerConfig.max_turns,
    ) -> None:
        if lookahead <= 0.0 or stuck_steps < 1 or stuck_progress < 0.0 or escape_turns < 1 or max_turns < 1:
            raise ValueError("LocalPlanner needs lookahead > 0, stuck_steps, escape_turns, max_turns >= 1")
        self.lookahead = lookahead
        self.stuck_steps = stuck_steps
        self.stuck_progress = stuck_progress
        self.escape_turns = escape_turns
        self.max_turns = max_turns
        self._step = sim.forward_step
        self._half_turn = math.radians(sim.turn_angle_deg) / 2.0
        self._max_escape_turns = max(1, round(180.0 / sim.turn_angle_deg))
        self.reset()

    @staticmethod
    def from_config(sim: SimConfig, config: PlannerConfig) -> LocalPlanner:
        """A planner tuned by ``config``."""
        c = config
        return LocalPlanner(sim, c.lookahead, c.stuck_steps, c.stuck_progress, c.escape_turns, c.max_turns)

    @property
    def escaping(self) -> bool:
        """Whether the last action came from a collision escape."""
        return self._escaping

    def reset(self) -> None:
        """Forget the escape plan, the collision streak and the stuck history (call on every new goal)."""
        self.failure = ""
        self._escape: deque[Action] = deque()
        self._escaping = False
        self._side = 0  # +1: escape to the left, -1: to the right, 0: not chosen
        self._streak = 0
        self._moves: deque[tuple[float, float]] = deque(maxlen=self.stuck_steps)
        self._turns_in_row = 0
        self._last: tuple[Action, float, float] | None = None  # last action and where it was issued

    def act(self, path: Polyline | None, pose: Pose, collided: bool, free: FreeSpace | None = None) -> Action | None:
        """The next action toward the end of ``path``, or ``None`` (see :attr:`failure`).

        ``collided`` is the observation's flag for the previous action. ``free`` (the map's navigable space)
        keeps the pursuit point in line of sight, so the robot does not cut corners through obstacles.
        """
        if path is None or len(path) < 2:
            self._fail("no_path", forget=False)
            return None
        if reached(path, pose, 0.5 * self._step):
            self._fail("at_goal", forget=False)
            return None
        self._after_previous(path, pose, collided)
        if self._is_stuck(pose):
            self._fail("stuck", forget=True)
            return None
        self._escaping = bool(self._escape)
        action = self._escape.popleft() if self._escaping else self._pursue(path, pose, free)
        if action != Action.MOVE_FORWARD and self._turns_in_row >= self.max_turns:
            self._fail("spinning", forget=True)
            return None
        return self._issue(action, pose)

    def carrot(self, path: Polyline, pose: Pose, lookahead: float | None = None) -> tuple[float, float]:
        """The pursuit point: walking ``path`` on from its vertex nearest the robot, the first crossing with
        the lookahead circle, or the end of the path inside it (the nearest vertex if it lies outside)."""
        nearest = int(np.argmin(np.hypot(path[:, 0] - pose.x, path[:, 1] - pose.y)))
        return circle_crossing(path[nearest:], (pose.x, pose.y), lookahead or self.lookahead)

    def _visible_carrot(self, path: Polyline, pose: Pose, free: FreeSpace | None) -> tuple[float, float]:
        """The farthest pursuit point (lookahead shrinking toward one step) the robot can see in ``free``."""
        lookahead = self.lookahead
        while True:
            point = self.carrot(path, pose, lookahead)
            if free is None or lookahead <= self._step or _segment_free(free, (pose.x, pose.y), point, OWN_CELL):
                return point
            lookahead = max(self._step, 0.6 * lookahead)

    def _pursue(self, path: Polyline, pose: Pose, free: FreeSpace | None) -> Action:
        error = heading_error(pose, self._visible_carrot(path, pose, free))
        if abs(error) <= self._half_turn:
            return Action.MOVE_FORWARD
        return Action.TURN_LEFT if error > 0.0 else Action.TURN_RIGHT

    def _after_previous(self, path: Polyline, pose: Pose, collided: bool) -> None:
        """Start or escalate an escape after a blocked forward step; end the streak after a clean one."""
        if self._last is None or self._last[0] != Action.MOVE_FORWARD:
            return
        moved = math.hypot(pose.x - self._last[1], pose.y - self._last[2])
        if collided and moved < 0.5 * self._step:
            self._streak += 1
            self._side = self._side or self._bend_side(path, pose)
            turn = Action.TURN_LEFT if self._side > 0 else Action.TURN_RIGHT
            turns = min(self.escape_turns * self._streak, self._max_escape_turns)
            self._escape = deque([turn] * turns + [Action.MOVE_FORWARD])
        elif not self._escaping:
            self._streak = 0
            self._side = 0

    def _bend_side(self, path: Polyline, pose: Pose) -> int:
        """+1 if the path leads off to the left of the heading, -1 if to the right (left when dead ahead)."""
        for point in (self.carrot(path, pose), (float(path[-1, 0]), float(path[-1, 1]))):
            error = heading_error(pose, point)
            if abs(error) > 1e-6:
                return 1 if error > 0.0 else -1
        return 1

    def _is_stuck(self, pose: Pose) -> bool:
        if len(self._moves) < self.stuck_steps:
            return False
        x0, y0 = self._moves[0]
        return math.hypot(pose.x - x0, pose.y - y0) < self.stuck_progress

    def _issue(self, action: Action, pose: Pose) -> Action:
        if action == Action.MOVE_FORWARD:
            self._moves.append((pose.x, pose.y))
            self._turns_in_row = 0
        else:
            self._turns_in_row += 1
        self._last = (action, pose.x, pose.y)
        self.failure = ""
        return action

    def _fail(self, reason: str, forget: bool) -> None:
        if forget:
            self.reset()
        self.failure = reason


def _segment_free(free: FreeSpace, start: tuple[float, float], end: tuple[float, float], skip: float) -> bool:
    """Whether ``free`` holds along the segment, ignoring its first ``skip`` metres."""
    length = math.dist(start, end)
    samples = max(2, int(length / 0.05) + 1)
    for t in np.linspace(0.0, 1.0, samples):
        if t * length < skip:
            continue
        if not free(start[0] + t * (end[0] - start[0]), start[1] + t * (end[1] - start[1])):
            return False
    return True

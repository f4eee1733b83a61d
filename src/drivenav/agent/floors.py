"""Floors in the agent body (docs/floors.md, "The body's floors"): one set of maps per floor, the floor known from
the pose's height, stairs taken when the reasoner judges the target on another floor or a floor has nothing left
to explore.

**Floors from heights.** The pose's height (``Observation.pose.z``: above the start, as odometry or habitat's agent
state gives it) places the agent on a *level*: the start's is 0; a height within :attr:`FloorsConfig.level_tolerance`
of a known level is on it; a height held steady at least :attr:`FloorsConfig.new_level` away from every known level
is a new one (a half landing, half a storey up, is none). Between levels the agent is on stairs, and stays on the
floor it left until it arrives: hysteresis, so that no frame taken on a staircase is fused into a floor's map.

**One set of maps per floor.** Each floor has its own :class:`~drivenav.agent.state.BodyState` -- mapper (with its
stair layers, :mod:`drivenav.mapping.stairs`), directions pipeline, planner, target search and object map -- and
its own explorer (its memory: representative views, value maps); the reasoner, the grounder, the body's counters and
the reasoner's hints are the episode's. A floor first reached begins as the episode did (DRIVE-Nav's start scan).

**The floor rule.** A floor is left for another in two cases. (1) *The floor question*: once
:attr:`FloorsConfig.min_floor_steps` were spent on the floor, and every :attr:`FloorsConfig.ask_every` steps after,
while a way to a floor neither explored nor judged is known, the reasoner is shown the floor's album (frames spread over
the stay on it) and asked whether the target is likely on this floor; on ``other`` the agent sets off by a way within
:attr:`FloorsConfig.near_way` of it (looked for at every step after; once per floor). (2) *Exhaustion*: the floor's
explorer finds nothing left to explore on it (the ``no_frontier`` STOP of every method). Either way the agent takes a
way to another floor that it knows (the stairs it came by) or sees (:func:`~drivenav.mapping.stairs.find_stairs`: a
flight rising from the floor, a stairwell's opening), to a floor not yet exhausted -- an unknown floor first, then the
nearest -- and STOPs as before when there is none. ASCENT asks its floor question only when no near frontier is left
(:attr:`FloorsConfig.near_frontier`, off by default) and keeps a minimum of steps between floor changes; here the
minimum is the steps on a floor before it is asked, and exhaustion is the fallback. With
:attr:`FloorsConfig.recheck` (on by default) a floor reached after ``other`` whose every way leads back to floors
judged so is asked too, and ``other`` there sends the agent back. With :attr:`FloorsConfig.railings` (off by default)
a way down suspected behind a railing (:func:`~drivenav.mapping.stairs.find_railings`) counts as a way to an unknown
floor while no way down is known: the agent goes to look from beyond the railing's end (:meth:`Floors._look`), and
the way down, if the look shows one, is taken like any other.

**Taking stairs.** The agent drives on its floor's map to the stairs' entry, turns to their heading, and drives
along it (:meth:`Floors.climb`), its maps frozen, until it stands on a level again; until it leaves its level it
keeps to the line through the entry along the heading (:func:`_line_heading`: its turns seldom face a flight's
heading exactly); a way on which
:attr:`FloorsConfig.probe_steps` forward steps change the height by less than half a step, or whose entry takes
more than :attr:`FloorsConfig.approach_steps` to reach, is dropped; one whose entry the map cannot reach yet rests
and is tried again :attr:`FloorsConfig.retry_steps` later. The stairs it used are remembered both ways (a *portal*).

On a world without floors no height ever changes and no stairs are found: every record is what it was. With
``agent.floors.enabled`` false the body is the planar one a method was published with.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from drivenav.agent.config import FloorsConfig
from drivenav.agent.context import Point, StepContext, replan
from drivenav.agent.trace import FloorDropped, FloorJudged, FloorLooked, FloorReached, FloorSetOff
from drivenav.inspection import turn_toward
from drivenav.inspection.views import frame_view
from drivenav.mapping.stairs import StairCandidate, find_railings, find_stairs
from drivenav.semantics.protocols import View
from drivenav.types import Action, Observation

if TYPE_CHECKING:
    from drivenav.agent.explorer import Explorer
    from drivenav.agent.handles import StepHandles
    from drivenav.agent.state import BodyState

NO_FRONTIER = "no_frontier"
STAIRS = "stairs"  # the steps-by-activity name of the steps spent going to and on stairs


@dataclass
class Floor:
    """One floor of the episode: its level (height above the start), its body state and explorer, whether its
    explorer found nothing left, the step the agent last arrived on it, whether its explorer has begun, its album
    (frames taken on it, what the floor question shows) and the steps between them (0: not yet thinned), whether
    the reasoner judged the target on another floor, the step it was last asked, whether it was left by the
    share rule, how many ``other`` answers in a row it had, and whether it was judged without the target on a
    recheck (:attr:`FloorsConfig.recheck`: then it is left by any way back, not only a near one)."""

    level: float
    state: BodyState
    explorer: Explorer
    exhausted: bool = False
    arrived: int = 0
    begun: bool = True
    album: list[View] = field(default_factory=list)
    album_every: int = 0
    judged_other: bool = False
    asked: int = -1
    overstayed: bool = False
    others: int = 0
    rechecked: bool = False


@dataclass(frozen=True)
class Portal:
    """Stairs the agent took: from ``floor`` at ``entry`` along ``heading`` they lead to floor ``to``."""

    floor: int
    entry: Point
    heading: float
    to: int


@dataclass
class StairTrip:
    """Stairs being taken: the way (entry, heading, up or down, the floor it leads to if known), the phase
    (``approach``: driving to the entry on the map; ``turn``: facing the heading; ``climb``: on the way; for a
    suspected way, ``toward`` and ``face``: driving on to the point to look from, facing along the railing), its
    counts, where the last step on it set off, the detour under way (+1 left, -1 right, 0 none), the side the last
    forward step went off the heading (0: on it) and how many steps toward the entry collided without moving."""

    way: StairCandidate
    to: int | None
    phase: str = "approach"
    steps: int = 0
    forward: int = 0
    left_level: bool = False
    last_height: float = 0.0
    steady: int = 0
    last_xy: Point = (math.inf, math.inf)
    detour: int = 0
    side: int = 0
    blocked: int = 0

    def stuck(self, observation: Observation) -> bool:
        """Whether the step just taken collided without moving (less than :data:`STILL` from where it set off)."""
        pose = observation.pose
        return observation.collided and math.dist((pose.x, pose.y), self.last_xy) < STILL


STILL = 0.05  # metres: a colliding step that moved less than this did not move
LOOKED_NEAR = 1.0  # metres: a suspected way this near a place the agent looked from was looked at
ON_FLOOR = 0.05  # metres from a level's height at which the agent is off the stairs (a tread is 0.15 m or more)
BLOCKED_STEPS = 3  # steps toward an entry that collided without moving, before the agent sets off from near it
BLOCKED_NEAR = 1.0  # metres from the entry that count as near it then
LINE_BAND = 0.1  # metres off a flight's centre line before the agent steers back to it (:func:`_line_heading`)
LINE_AHEAD = 0.5  # metres along the centre line to the point steered for (two forward steps)

NewFloor = Callable[[], tuple["BodyState", "Explorer"]]
"""Makes a floor's body state and explorer (the body's, for a floor first reached)."""
SwitchFloor = Callable[[Floor], None]
"""Makes a floor's state and explorer the body's current ones."""


class Floors:
    """The episode's floors, the current one, and the stairs being taken (module docstring)."""

    def __init__(
        self, config: FloorsConfig, first: Floor, new_floor: NewFloor, switch: SwitchFloor, budget: int
    ) -> None:
        self.config = config
        self.budget = budget  # the episode's steps
        self._new_floor = new_floor
        self._switch = switch
        self.floors: list[Floor] = [first]
        self.current = 0
        self.trip: StairTrip | None = None
        self.portals: list[Portal] = []
        self.dropped: list[StairCandidate] = []
        self.resting: list[tuple[StairCandidate, int]] = []  # ways whose entry the map could not reach, until a step
        self.looked: list[Point] = []  # where the agent looked for a suspected way (agent.floors.railings)
        self.changes = 0

    @property
    def floor(self) -> Floor:
        return self.floors[self.current]

    def explorers(self) -> list[Explorer]:
        return [f.explorer for f in self.floors]

    def states(self) -> list[BodyState]:
        return [f.state for f in self.floors]

    # ------------------------------------------------------------------------------------------- floor rule

    def look(self, observation: Observation) -> None:
        """Keep a frame of the floor in its album every ``album_every`` steps on it; past ``album_size`` frames, every
        other one is let go and the interval doubles: the album spans the whole stay on the floor, evenly."""
        floor, config = self.floor, self.config
        every = floor.album_every or config.album_every
        if (observation.step - floor.arrived) % every != 0:
            return
        floor.album = [*floor.album, frame_view(observation)]
        if len(floor.album) > config.album_size:
            floor.album, floor.album_every = floor.album[::2], 2 * every

    def ask(self, handles: StepHandles, ctx: StepContext) -> bool:
        """Every ``ask_every`` steps once ``min_floor_steps`` were spent on the floor, while a way to a floor neither
        explored nor judged without the target is known: the share rule (the floor had its share of the steps and a
        floor not yet visited is in reach), then the floor question (the reasoner judges the target on another
        floor; once it did, the agent sets off again at each question's turn until it leaves); where every way
        leads to a floor judged so, the recheck (:meth:`_recheck`, a switch). Either sets off (True)."""
        floor, config = self.floor, self.config
        on_floor = handles.step - floor.arrived
        waiting = floor.judged_other and config.near_way > 0.0  # judged, a way not yet near: look at every step
        due = floor.asked < 0 or handles.step - floor.asked >= config.ask_every or waiting
        if on_floor < config.min_floor_steps or not due:
            return False
        if not floor.judged_other and _frontier_within(ctx, config.near_frontier):
            return False  # ASCENT's timing: the floor still has a frontier near; asked again at the next step
        floor.asked = handles.step
        known = [w for w in self._ways(ctx) if self._usable(w, handles.step)]
        ways = [w for w in known if self._open(w)]
        if floor.judged_other:  # judged so before and the way not taken (its entry out of reach or far then): again
            back = [w for w in known if self._worth(w)] if floor.rechecked else []
            return self._set_off(handles, ctx, self._near(ctx, ways) if ways else back, "judged")
        if not ways and config.recheck and config.ask:
            return self._recheck(handles, ctx, [w for w in known if self._worth(w)])
        unvisited = [w for w in ways if w[1] is None]
        if unvisited and not floor.overstayed and on_floor >= config.share * (self.budget - floor.arrived):
            floor.overstayed = True
            return self._set_off(handles, ctx, unvisited, "share")
        if not ways or not config.ask:
            return False
        guess = self._judge(handles)
        floor.others = floor.others + 1 if guess == "other" else 0
        if floor.others < config.confirm:
            return False
        floor.judged_other = True
        return self._set_off(handles, ctx, self._near(ctx, ways), "judged")

    def _recheck(self, handles: StepHandles, ctx: StepContext, ways: list[tuple[StairCandidate, int | None]]) -> bool:
        """The floor question on a floor whose every way leads to a floor judged without the target
        (:attr:`FloorsConfig.recheck`): ``other`` here too contradicts the earlier answer, and the agent goes back
        by the nearest way, however far (True; where its entry cannot be reached yet, again at the next turns);
        the floor it goes back to stays judged, and this floor is now judged too, so neither is left for the
        other on the reasoner's word again."""
        if not ways:
            return False
        if self._judge(handles) != "other":
            return False
        floor = self.floor
        floor.judged_other = floor.rechecked = True
        return self._set_off(handles, ctx, ways, "judged")

    def _judge(self, handles: StepHandles) -> str:
        """The floor question on the current floor (its album shown), traced; the reasoner's guess."""
        judgement = handles.state.reasoner.judge_floor(handles.host.goal_text, self.floor.album)
        handles.trace.add(FloorJudged(handles.step, self.current, judgement.guess, judgement.note))
        return judgement.guess

    def _near(
        self, ctx: StepContext, ways: list[tuple[StairCandidate, int | None]]
    ) -> list[tuple[StairCandidate, int | None]]:
        """The ways whose entry lies within :attr:`FloorsConfig.near_way` of the agent (all of them at 0): a floor
        judged without the target is left by a way met on the explorer's own course, not by crossing the floor."""
        reach = self.config.near_way
        if reach <= 0.0:
            return ways
        here = (ctx.pose.x, ctx.pose.y)
        return [w for w in ways if not w[0].seen or math.dist(here, w[0].entry) <= reach]

    def leave(self, handles: StepHandles, ctx: StepContext) -> bool:
        """The current floor has nothing left to explore: set off for the best way to another floor not yet
        exhausted (True), or say there is none (False: the agent STOPs)."""
        self.floor.exhausted = True
        ways = [w for w in self._ways(ctx) if self._worth(w) and self._usable(w, handles.step)]
        return self._set_off(handles, ctx, ways, "explored")

    def _set_off(
        self, handles: StepHandles, ctx: StepContext, ways: list[tuple[StairCandidate, int | None]], reason: str
    ) -> bool:
        """Set off for the way to an unknown floor first, else the nearest (True); False when there is none."""
        if not ways:
            return False
        here = (ctx.pose.x, ctx.pose.y)
        way, to = min(ways, key=lambda item: (self._known(item[1]), not item[0].seen, math.dist(here, item[0].entry)))
        self.trip = StairTrip(way, to)
        handles.trace.add(FloorSetOff(handles.step, self.current, way.entry, way.up, reason))
        handles.state.goal = None
        handles.state.planner.reset()
        handles.start_segment()
        return True

    def _ways(self, ctx: StepContext) -> list[tuple[StairCandidate, int | None]]:
        """The ways off the current floor with the floor each leads to (None: not known): its portals, then the
        stairs its maps show that no portal already is."""
        ways: list[tuple[StairCandidate, int | None]] = [
            (StairCandidate(p.entry, p.heading, self.floors[p.to].level > self.floor.level), p.to)
            for p in self.portals
            if p.floor == self.current
        ]
        relief = self.floor.state.mapper.relief()
        if relief is not None:
            for seen in find_stairs(relief, ctx.snapshot, self.config.stairs):
                if not any(math.dist(seen.entry, w.entry) < 1.0 for w, _ in ways):
                    ways.append((seen, self._next_level(seen.up)))
            if self.config.railings and not any(not w.up for w, _ in ways):
                ways += [
                    (s, None) for s in find_railings(relief, ctx.snapshot, self.config.stairs) if self._unlooked(s)
                ]
        return ways

    def _unlooked(self, suspect: StairCandidate) -> bool:
        """A suspected way not yet looked at (within :data:`LOOKED_NEAR` of a place the agent looked from)."""
        return all(math.dist(suspect.entry, point) >= LOOKED_NEAR for point in self.looked)

    def _next_level(self, up: bool) -> int | None:
        """The known floor next above (or below) the current one, None if none is known."""
        level = self.floor.level
        others = [
            (abs(f.level - level), k)
            for k, f in enumerate(self.floors)
            if (f.level > level) == up and k != self.current
        ]
        return min(others)[1] if others else None

    def _worth(self, way: tuple[StairCandidate, int | None]) -> bool:
        return way[1] is None or not self.floors[way[1]].exhausted

    def _open(self, way: tuple[StairCandidate, int | None]) -> bool:
        """A way worth taking on the reasoner's word: to a floor neither explored nor judged without the target."""
        return way[1] is None or not (self.floors[way[1]].exhausted or self.floors[way[1]].judged_other)

    def _known(self, to: int | None) -> bool:
        """Unknown floors first."""
        return to is not None

    def _usable(self, way: tuple[StairCandidate, int | None], step: int) -> bool:
        """Neither dropped for good nor resting: an entry the map could not reach is tried again
        :attr:`FloorsConfig.retry_steps` later, not at the next step (else the agent sets off every step)."""
        entry = way[0].entry
        if any(math.dist(entry, d.entry) < 0.5 for d in self.dropped):
            return False
        return not any(math.dist(entry, r.entry) < 0.5 and step < until for r, until in self.resting)

    # ----------------------------------------------------------------------------------------- taking stairs

    def heading_for_stairs(self, handles: StepHandles, observation: Observation, ctx: StepContext) -> Action | None:
        """A step toward the stairs' entry on the map (``approach``), then of turning to their heading (``turn``),
        then the first step along it; None when the way was dropped (the explorer goes on)."""
        trip = self.trip
        assert trip is not None
        trip.steps += 1
        if trip.steps > self.config.approach_steps:
            return self._drop(handles, "approach_steps")
        if trip.phase == "approach":
            action = self._approach(handles, observation, ctx, trip)
            if action is not None:
                return action
        if not trip.way.seen:
            return self._look(handles, observation, trip)
        return self._turn(handles, observation, trip)

    def _look(self, handles: StepHandles, observation: Observation, trip: StairTrip) -> Action | None:
        """At a suspected way (:func:`~drivenav.mapping.stairs.find_railings`): drive on toward the point to look
        from -- off the map's navigable floor, as the strip where stairs arrive is rarely seen before -- until
        within :data:`LOOKED_NEAR` of it, after :attr:`FloorsConfig.look_steps` forward steps or once a step
        collides without moving; then face along the railing. Then the trip ends (None: the explorer acts) and the
        maps hold the stairwell's drops if it is there: a way down the floor rule takes like any other."""
        pose, turn = observation.pose, handles.tuning.turn
        here = (pose.x, pose.y)
        stuck = trip.stuck(observation)
        if trip.phase != "face":
            trip.phase = "toward"
            gap = math.dist(here, trip.way.entry)
            if gap <= LOOKED_NEAR / 2.0 or trip.forward >= self.config.look_steps or stuck:
                trip.phase = "face"
            else:
                bearing = math.atan2(trip.way.entry[1] - pose.y, trip.way.entry[0] - pose.x)
                action = turn_toward(pose.yaw, bearing, turn)
                if action is not None:
                    return action
                trip.forward += 1
                trip.last_xy = here
                return Action.MOVE_FORWARD
        action = turn_toward(pose.yaw, trip.way.heading, turn)
        if action is not None:
            return action
        self.looked.append(trip.way.entry)
        handles.trace.add(FloorLooked(handles.step, self.current, trip.way.entry))
        self._end_trip(handles)
        return None

    def _approach(
        self, handles: StepHandles, observation: Observation, ctx: StepContext, trip: StairTrip
    ) -> Action | None:
        """A planned step toward the way's entry; None once there -- or near it (``BLOCKED_NEAR``) after
        ``BLOCKED_STEPS`` steps that collided without moving: by a stairwell's edge the map and the world part, and
        driving along the heading (with its detours) goes on from there."""
        pose = observation.pose
        here = (pose.x, pose.y)
        goal = _navigable_near(ctx, trip.way)
        if goal is None:
            return self._drop(handles, "unreachable", remember=False)
        trip.blocked += trip.stuck(observation)
        trip.last_xy = here
        near = math.dist(here, goal)
        if near <= self.config.entry_tolerance or (trip.blocked >= BLOCKED_STEPS and near <= BLOCKED_NEAR):
            trip.phase = "turn"
            return None
        state = handles.state
        state.goal = goal
        planned = replan(state.pipeline, ctx, goal)
        action = state.planner.act(planned.goal_path, ctx.pose, observation.collided, planned.free)
        return action if action is not None else self._drop(handles, "no_path", remember=False)

    def _turn(self, handles: StepHandles, observation: Observation, trip: StairTrip) -> Action:
        action = turn_toward(observation.pose.yaw, _line_heading(observation, trip), handles.tuning.turn)
        if action is not None:
            return action
        trip.phase = "climb"
        trip.steps = 0
        trip.last_height = observation.pose.z
        handles.state.planner.reset()
        return Action.MOVE_FORWARD

    def on_stairs(self, observation: Observation) -> bool:
        """Whether this step is one of climbing (the trip's ``climb`` phase): the maps are left as they are."""
        return self.trip is not None and self.trip.phase == "climb"

    def climb(self, handles: StepHandles, observation: Observation) -> Action | None:
        """A step along the stairs' heading; None when the agent arrived on a level -- within :data:`ON_FLOOR` of
        its height, off the last tread (the floors switched, the step goes on there) -- or gave the stairs up (back
        on the floor it left)."""
        trip = self.trip
        assert trip is not None
        z = observation.pose.z
        level = self._level_at(z)
        if trip.left_level and level is not None and abs(z - self.floors[level].level) <= ON_FLOOR:
            if level == self.current:  # back where it set off, the stairs given up
                self.trip = None
                handles.state.planner.reset()
            else:
                self._arrive(handles, level, observation)
            return None
        if not trip.left_level and abs(z - self.floor.level) > self.config.level_tolerance:
            trip.left_level = True
        trip.steady = trip.steady + 1 if abs(z - trip.last_height) < 0.01 else 0
        trip.last_height = z
        if trip.left_level and level is None and trip.steady >= 2 and self._new_level(z):
            self._arrive(handles, self._add_level(z), observation)
            return None
        trip.steps += 1
        moved = abs(z - self.floor.level) >= self.config.stairs.climb / 2.0
        if not trip.left_level and not moved and trip.forward >= self.config.probe_steps:
            self._drop(handles, "no_climb")
            return None
        if trip.steps > self.config.climb_steps:
            self._turn_back(handles, trip)
        return self._along(handles, observation, trip)

    def _turn_back(self, handles: StepHandles, trip: StairTrip) -> None:
        """Stairs given up between two levels: back the way the agent came, to the floor it left (once; after
        that it goes on as it can)."""
        if trip.to == self.current:
            return
        way = trip.way
        back = StairCandidate(way.entry, math.remainder(way.heading + math.pi, 2.0 * math.pi), not way.up)
        self.dropped.append(way)
        handles.trace.add(FloorDropped(handles.step, self.current, way.entry, "climb_steps"))
        trip.way, trip.to, trip.steps = back, self.current, 0

    def _along(self, handles: StepHandles, observation: Observation, trip: StairTrip) -> Action:
        """Face the stairs' heading and drive: no planner on stairs (its escape from a collision turns away; the
        world slides the agent along a railing it meets at an angle, so driving on follows the flight). A forward
        step that collided without moving is followed by one step a turn off the heading, toward the side the
        depth frame shows more open (:func:`_open_side`), then the heading again; where that step collided too, the
        next goes a turn off to the other side (else the agent would push the same way until it gives the stairs
        up: on a development set, wedged at a flight's foot for 120 steps). Until the agent leaves its level it keeps
        to the flight's centre line (:func:`_line_heading`)."""
        pose = observation.pose
        stuck = trip.stuck(observation)
        if trip.detour == 0 and stuck:  # a detour step that collided too: the other side next
            trip.detour = -trip.side if trip.side else _open_side(observation)
        turn = handles.tuning.turn
        action = turn_toward(pose.yaw, _line_heading(observation, trip) + trip.detour * turn, turn)
        if action is not None:
            return action
        trip.side, trip.detour = trip.detour, 0
        trip.forward += 1
        trip.last_xy = (pose.x, pose.y)
        return Action.MOVE_FORWARD

    def _level_at(self, z: float) -> int | None:
        near = [
            (abs(z - f.level), k) for k, f in enumerate(self.floors) if abs(z - f.level) <= self.config.level_tolerance
        ]
        return min(near)[1] if near else None

    def _new_level(self, z: float) -> bool:
        return all(abs(z - f.level) >= self.config.new_level for f in self.floors)

    def _add_level(self, z: float) -> int:
        state, explorer = self._new_floor()
        self.floors.append(Floor(z, state, explorer, begun=False))
        return len(self.floors) - 1

    def _arrive(self, handles: StepHandles, level: int, observation: Observation) -> None:
        """On floor ``level``: the portal both ways, the floor's state and explorer take over."""
        trip = self.trip
        assert trip is not None
        here = (observation.pose.x, observation.pose.y)
        self.portals.append(Portal(self.current, trip.way.entry, trip.way.heading, level))
        self.portals.append(
            Portal(level, here, math.remainder(trip.way.heading + math.pi, 2.0 * math.pi), self.current)
        )
        self.trip = None
        handles.trace.add(FloorReached(handles.step, level, self.current, not self.floors[level].begun))
        self.current = level
        self.changes += 1
        floor = self.floor
        floor.arrived = handles.step
        floor.exhausted = False
        self._switch(floor)

    def _drop(self, handles: StepHandles, reason: str, remember: bool = True) -> Action | None:
        """Give the way up for ``reason`` (traced: :class:`FloorDropped`) and go on exploring the floor (which STOPs
        again if nothing is left); ``remember``: never take it again (else, for an entry the map cannot reach yet,
        not for :attr:`FloorsConfig.retry_steps`: it may be reached later)."""
        trip = self.trip
        assert trip is not None
        handles.trace.add(FloorDropped(handles.step, self.current, trip.way.entry, reason))
        if remember:
            self.dropped.append(trip.way)
        else:
            self.resting.append((trip.way, handles.step + self.config.retry_steps))
        self._end_trip(handles)
        return None

    def _end_trip(self, handles: StepHandles) -> None:
        """The trip is over on the floor it set off from: the explorer acts again, from a fresh course."""
        self.trip = None
        handles.state.goal = None
        handles.state.planner.reset()


def _frontier_within(ctx: StepContext, reach: float) -> bool:
    """Whether a frontier of the floor's map has a cell within ``reach`` metres of the agent (never at 0)."""
    if reach <= 0.0:
        return False
    here = np.array([ctx.pose.x, ctx.pose.y])
    return any(float(np.min(np.hypot(*(f.points - here).T))) <= reach for f in ctx.frontiers if len(f.points))


def _line_heading(observation: Observation, trip: StairTrip) -> float:
    """The heading to drive toward the stairs: the way's own, or, while the agent has not left its level and stands
    more than :data:`LINE_BAND` to one side of the line through the entry along that heading (the flight's centre
    line), toward the point :data:`LINE_AHEAD` metres ahead on it. Turns come in steps of 30 degrees from the
    episode's start heading, so the agent can face a flight's heading only to within 15 degrees, and each step so
    far off drifts 6.5 cm sideways: from a foot reached to one side of the line it drifted into the flight's side
    wall and was stopped there (a development episode, its way given up after the probe's steps). The band is the
    room beside the narrowest flight (0.75 m less the agent's 0.36 m, halved: 0.195 m) less one such drift. Once on
    the stairs the way's heading alone: a flight's line holds for its first flight only."""
    way, pose = trip.way, observation.pose
    if trip.left_level:
        return way.heading
    offset = math.cos(way.heading) * (pose.y - way.entry[1]) - math.sin(way.heading) * (pose.x - way.entry[0])
    if abs(offset) <= LINE_BAND:
        return way.heading
    return way.heading - math.atan2(offset, LINE_AHEAD)


def _open_side(observation: Observation) -> int:
    """+1 (left) or -1 (right): the half of the depth frame's middle rows that sees farther (median depth)."""
    depth = observation.depth
    rows, cols = depth.shape
    band = depth[rows * 3 // 8 : rows * 5 // 8]
    left, right = (float(np.nanmedian(half)) for half in (band[:, : cols // 2], band[:, cols // 2 :]))
    return 1 if left >= right else -1


def _navigable_near(ctx: StepContext, way: StairCandidate) -> Point | None:
    """The navigable point nearest the entry back along the way's heading (the entry of a flight seen from the
    floor lies against its first step, in the obstacles' inflation), within :data:`ENTRY_REACH`; else the
    navigable point nearest the entry in any direction within that reach (where the agent arrived at the top of a
    flight, the floor back along the way's heading may be a strip too narrow for the inflation, the stairwell's
    drops beside it)."""
    back = (-math.cos(way.heading), -math.sin(way.heading))
    steps = round(ENTRY_REACH / 0.05)
    for k in range(steps + 1):
        point = (way.entry[0] + back[0] * 0.05 * k, way.entry[1] + back[1] * 0.05 * k)
        if ctx.free(*point):
            return point
    snapshot = ctx.snapshot
    grid, reach = snapshot.grid, math.ceil(ENTRY_REACH / snapshot.grid.resolution) + 1
    row, col = grid.cell_at(*way.entry)  # only cells this near can lie within the reach
    r0, c0 = max(row - reach, 0), max(col - reach, 0)
    cells = np.argwhere(snapshot.navigable[r0 : max(row + reach + 1, 0), c0 : max(col + reach + 1, 0)])
    if not len(cells):
        return None
    points = grid.cell_to_world(cells + np.array([r0, c0]))
    gaps = np.hypot(*(points - np.asarray(way.entry)).T)
    nearest = int(np.argmin(gaps))
    if gaps[nearest] > ENTRY_REACH:
        return None
    return float(points[nearest, 0]), float(points[nearest, 1])


ENTRY_REACH = 1.5  # metres from a way's entry within which the agent looks for navigable floor to set out from

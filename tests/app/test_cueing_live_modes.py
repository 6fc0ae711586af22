"""live.pipeline_modes: every (mode, event) pair of the live pipeline's transition table against
the rules as written here, and the rules' own consequences over the whole table: an emergency
stop is accepted everywhere and ends in STOPPED; nothing but a park leaves STOPPED; telemetry
moves the platform only from STARTING or FADING (a resume); every mode is reachable from
STARTING and every mode can get back to PARKED."""
from __future__ import annotations

import itertools

import pytest

from stewart_sim.live.pipeline_modes import (
    TABLE,
    Event,
    Mode,
    at_rest,
    fading,
    follows_telemetry,
    transition,
)

# The rules: the mode after each event, "!" + a word of the refusal for the operator's and the
# telemetry's events refused, "-" for an event of the pipeline's own refused because it cannot
# happen in that mode (the loss timer, the fade's end).
GRID = """
          TELEMETRY   LOSS     PARK     ESTOP    FADE_DONE  RESUME
STARTING  RUNNING     -        PARKING  STOPPED  -          !resume
RUNNING   RUNNING     FADING   PARKING  STOPPED  -          !resume
FADING    RUNNING     -        PARKING  STOPPED  STARTING   !resume
PARKING   !telemetry  -        PARKING  STOPPED  PARKED     !resume
PARKED    !telemetry  -        PARKED   STOPPED  -          STARTING
STOPPED   !telemetry  -        PARKING  STOPPED  -          !resume
"""


def _rules() -> dict[tuple[Mode, Event], str]:
    head, *rows = [line.split() for line in GRID.strip().splitlines()]
    return {(Mode[row[0]], Event[e]): cell for row in rows for e, cell in zip(head, row[1:])}


RULES = _rules()
PAIRS = list(itertools.product(Mode, Event))


def test_the_rules_and_the_table_cover_every_pair():
    assert len(PAIRS) == 36 and set(RULES) == set(PAIRS) == set(TABLE)


@pytest.mark.parametrize("mode, event", PAIRS, ids=[f"{m.name}-{e.name}" for m, e in PAIRS])
def test_transition(mode, event):
    rule, t = RULES[(mode, event)], transition(mode, event)
    if rule == "-":
        assert t.mode is mode and t.refusal
    elif rule.startswith("!"):
        assert t.mode is mode and rule[1:] in t.refusal.split()
    else:
        assert t.mode is Mode[rule] and t.refusal is None


def test_an_emergency_stop_is_accepted_everywhere():
    assert all(transition(m, Event.ESTOP) == transition(Mode.STOPPED, Event.ESTOP)
               and transition(m, Event.ESTOP).mode is Mode.STOPPED
               and transition(m, Event.ESTOP).refusal is None for m in Mode)


def test_only_a_park_leaves_the_emergency_stop():
    left = {e: transition(Mode.STOPPED, e).mode for e in Event}
    assert {e for e, m in left.items() if m is not Mode.STOPPED} == {Event.PARK}
    assert left[Event.PARK] is Mode.PARKING


def test_telemetry_moves_the_platform_only_when_the_pipeline_may_follow_it():
    """TELEMETRY enters RUNNING from STARTING and FADING (the resume, ramped in) only; the
    parked, parking and stopped platform ignores it, with a reason."""
    into = {m for m in Mode if m is not Mode.RUNNING
            and transition(m, Event.TELEMETRY).mode is Mode.RUNNING}
    assert into == {Mode.STARTING, Mode.FADING}
    ignored = {m for m in Mode if transition(m, Event.TELEMETRY).refusal}
    assert ignored == {Mode.PARKING, Mode.PARKED, Mode.STOPPED}
    assert all(transition(m, Event.TELEMETRY).mode is m for m in ignored)


def test_a_refusal_never_changes_the_mode():
    assert all(t.mode is m for (m, _), t in TABLE.items() if t.refusal is not None)


def test_every_mode_reachable_and_every_mode_can_park():
    """From STARTING every mode is reached; from every mode PARKED is reached (by accepted
    events only)."""
    def reach(start):
        seen, todo = {start}, [start]
        while todo:                       # at most len(Mode) modes are ever queued
            m = todo.pop()
            for e in Event:
                t = transition(m, e)
                if t.refusal is None and t.mode not in seen:
                    seen.add(t.mode)
                    todo.append(t.mode)
        return seen
    assert reach(Mode.STARTING) == set(Mode)
    assert all(Mode.PARKED in reach(m) for m in Mode)


def test_the_fades_end_where_they_should():
    """A fade after a loss ends waiting for telemetry; a park's ends parked."""
    assert transition(Mode.FADING, Event.FADE_DONE).mode is Mode.STARTING
    assert transition(Mode.PARKING, Event.FADE_DONE).mode is Mode.PARKED
    assert {m for m in Mode if fading(m)} == {Mode.FADING, Mode.PARKING}
    assert {m for m in Mode if follows_telemetry(m)} == {Mode.RUNNING}
    assert {m for m in Mode if at_rest(m)} == {Mode.STARTING, Mode.PARKED, Mode.STOPPED}
    assert not ({m for m in Mode if fading(m)} & {m for m in Mode if at_rest(m)})

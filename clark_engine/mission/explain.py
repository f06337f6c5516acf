"""Show an agent's resolved behaviour: as an indented tree and as a Mermaid state diagram.

This is what the engine will run, after blocks are expanded, defaults applied
and channel names resolved through the agent's profile; reading it is the
quickest way to see that a mission means what its author thinks.
"""

from __future__ import annotations

from typing import Any

from clark_engine.mission.model import Agent, Mission, State

_SHOWN_PARAMS = 6


def _value(value: Any) -> str:
    if isinstance(value, float):
        return f"{value:g}"
    if isinstance(value, list):
        if len(value) > 3:
            return f"[{len(value)} items]"
        return "[" + ", ".join(_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k}: {_value(v)}" for k, v in value.items()) + "}"
    return str(value)


def _label(state: State, agent: Agent) -> str:
    name = state.name or "(behavior)"
    if state.primitive is not None:
        text = f"{name}: {state.primitive}"
        if state.block:
            text += f" (block {state.block})"
        params = list(state.params.items())
        shown = []
        for key, value in params[:_SHOWN_PARAMS]:
            if key == "channel" and value in agent.hardware.channels:
                ch = agent.hardware.channels[value]
                where = f"rc {ch.rc}" if ch.rc is not None else f"servo {ch.servo}"
                value = f"{value} ({where}, {ch.pwm_min_us}/{ch.pwm_trim_us}/{ch.pwm_max_us} us)"
            shown.append(f"{key}={_value(value)}")
        if len(params) > _SHOWN_PARAMS:
            shown.append("...")
        return text + ("  " + " ".join(shown) if shown else "")
    if state.children:
        kind = "parallel" if state.parallel else f"machine, initial {state.initial}"
        text = f"{name}: {kind}"
        if state.block:
            text += f" (block {state.block})"
        return text
    return f"{name}: final" if state.final else f"{name}: empty"


def _flags(state: State) -> str:
    parts = []
    if state.final and state.kind != "final":
        parts.append("final")
    if state.timeout_s is not None:
        parts.append(f"timeout {state.timeout_s:g} s")
    for t in state.transitions:
        arrow = f"{t.event} -> {'.'.join(t.target) or '?'}"
        if t.condition:
            arrow += f" when {_value(t.condition)}"
        parts.append(arrow)
    return f"  [{'; '.join(parts)}]" if parts else ""


def tree(mission: Mission, agent: Agent) -> str:
    """The behaviour as an indented tree, one state per line."""
    header = f"{agent.name} (id {agent.id}, {agent.profile}) at {mission.loop_hz:g} Hz"
    if agent.behavior is None:
        return header + "\n  no behaviour: the agent only sends its telemetry\n"
    lines = [header]

    def walk(state: State, prefix: str, last: bool, top: bool) -> None:
        branch = "" if top else ("└─ " if last else "├─ ")
        lines.append(prefix + branch + _label(state, agent) + _flags(state))
        children = list(state.children.values())
        inner = prefix if top else prefix + ("   " if last else "│  ")
        for i, child in enumerate(children):
            walk(child, inner, i == len(children) - 1, False)

    walk(agent.behavior, "  ", True, True)
    return "\n".join(lines) + "\n"


def _mid(state: State) -> str:
    return "__".join(state.path) or "behavior"


def mermaid(mission: Mission, agent: Agent) -> str:
    """The behaviour as a Mermaid ``stateDiagram-v2`` (paste into any Markdown viewer)."""
    out = ["stateDiagram-v2"]
    if agent.behavior is None:
        out.append("    [*] --> idle")
        return "\n".join(out) + "\n"
    edges: list[str] = []

    def declare(state: State, indent: str) -> None:
        sid = _mid(state)
        label = _label(state, agent).replace(":", " -").replace('"', "'")
        # `id : text` and a bare `state id {` are the forms every Mermaid version reads;
        # `state "text" as id {` for composites trips known Mermaid parser bugs.
        out.append(f"{indent}{sid} : {label}")
        if state.children:
            out.append(f"{indent}state {sid} {{")
            children = list(state.children.values())
            if state.parallel:
                for i, child in enumerate(children):
                    if i:
                        out.append(f"{indent}    --")
                    out.append(f"{indent}    [*] --> {_mid(child)}")
                    declare(child, indent + "    ")
            else:
                if state.initial:
                    out.append(f"{indent}    [*] --> {_mid(state.children[state.initial])}")
                for child in children:
                    declare(child, indent + "    ")
                    if child.final:
                        out.append(f"{indent}    {_mid(child)} --> [*]")
            out.append(f"{indent}}}")
        for t in state.transitions:
            if t.target:
                target = agent.behavior.find(t.target) if agent.behavior else None
                if target is not None:
                    label = t.event + (" [when]" if t.condition else "")
                    edges.append(f"    {sid} --> {_mid(target)} : {label}")

    out.append(f"    [*] --> {_mid(agent.behavior)}")
    declare(agent.behavior, "    ")
    out.extend(edges)
    return "\n".join(out) + "\n"

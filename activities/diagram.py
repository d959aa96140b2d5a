"""Diagrams of behaviors: Graphviz dot and Mermaid, nested machines as clusters.

A container is drawn as a cluster with an entry point (the black dot) and its outcomes
(double circles); a transition to a container goes to its entry point, and one from a
container leaves from the outcome it names. ``active`` highlights the states of an
active path (``GAME/ROUNDS/ROUND/ASK``), as smach_viewer does.
"""

from __future__ import annotations

import re

from activities.spec import BehaviorSpec, StateSpec

LEAF_COLOR = "#dfe9f7"
ACTIVE_COLOR = "#ffd54f"


def _id(path: str) -> str:
    return "s_" + re.sub(r"\W", "_", path) if path else "s_root"


def _slug(text: str) -> str:
    return re.sub(r"\W", "_", text)


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _label(state: StateSpec) -> str:
    if state.block == "behavior":
        return f"{state.name}\\n(behavior {state.params.get('name')})"
    return f"{state.name}\\n[{state.block}]"


def _active_set(active: str) -> set[str]:
    out: set[str] = set()
    for branch in active.split(","):
        parts = [p for p in branch.split("/") if p]
        for i in range(1, len(parts) + 1):
            out.add("/".join(parts[:i]))
    return out


def _is_container(state: StateSpec) -> bool:
    return bool(state.states)


def to_dot(spec: BehaviorSpec, active: str = "") -> str:
    """The behavior as a Graphviz digraph."""
    lit = _active_set(active)
    lines = [
        f"digraph {_quote(spec.name)} {{",
        "  compound=true; rankdir=TB;",
        '  node [shape=box, style="rounded,filled", fillcolor="'
        + LEAF_COLOR
        + '", fontname="sans"];',
    ]
    edges: list[str] = []

    def entry(path: str, state: StateSpec) -> str:
        return _id(path) + "__entry" if _is_container(state) else _id(path)

    def container(state: StateSpec, path: str, indent: str) -> None:
        lines.append(f"{indent}{_id(path)}__entry [shape=point, width=0.15];")
        outcomes = state.outcomes()
        for outcome in outcomes:
            lines.append(
                f"{indent}{_id(path)}__out_{_slug(outcome)} "
                f"[shape=doublecircle, label={_quote(outcome)}, fillcolor=white, fontsize=10];"
            )
        children = state.states
        first = state.params.get("initial") or next(iter(children), None)
        for name, child in children.items():
            child_path = f"{path}/{name}" if path else name
            draw(child, child_path, indent)
        if state.block in ("state_machine", "sequence") and first is not None:
            target_path = f"{path}/{first}" if path else first
            edges.append(f"  {_id(path)}__entry -> {entry(target_path, children[first])};")
            for name, child in children.items():
                child_path = f"{path}/{name}" if path else name
                for outcome in child.outcomes() or ():
                    target = child.transitions.get(outcome, outcome)
                    src = (
                        f"{_id(child_path)}__out_{_slug(outcome)}"
                        if _is_container(child)
                        else _id(child_path)
                    )
                    if target in children:
                        dst = entry(f"{path}/{target}" if path else target, children[target])
                    else:
                        dst = f"{_id(path)}__out_{_slug(target)}"
                    edges.append(f"  {src} -> {dst} [label={_quote(outcome)}, fontsize=9];")
        else:
            for name, child in children.items():
                child_path = f"{path}/{name}" if path else name
                edges.append(f"  {_id(path)}__entry -> {entry(child_path, child)} [style=dashed];")

    def draw(state: StateSpec, path: str, indent: str) -> None:
        highlighted = path in lit
        if _is_container(state):
            lines.append(f"{indent}subgraph cluster_{_id(path)} {{")
            lines.append(f"{indent}  label={_quote(_label(state).replace(chr(92) + 'n', ' '))};")
            lines.append(f'{indent}  style="rounded{",filled" if highlighted else ""}";')
            if highlighted:
                lines.append(f'{indent}  fillcolor="#fff8e1";')
            if state.block == "concurrence" and state.params.get("outcome_map"):
                omap = "; ".join(
                    f"{o} when {', '.join(f'{k}={v}' for k, v in m.items())}"
                    for o, m in state.params["outcome_map"].items()
                )
                lines.append(f"{indent}  tooltip={_quote(omap)};")
            container(state, path, indent + "  ")
            lines.append(f"{indent}}}")
        else:
            color = f', fillcolor="{ACTIVE_COLOR}", penwidth=2' if highlighted else ""
            lines.append(f"{indent}{_id(path)} [label={_quote(_label(state))}{color}];")

    container(spec.root, "", "  ")
    lines.extend(edges)
    lines.append("}")
    return "\n".join(lines) + "\n"


def to_mermaid(spec: BehaviorSpec, active: str = "") -> str:
    """The behavior as a Mermaid state diagram (composite states for containers)."""
    lit = _active_set(active)
    lines = ["stateDiagram-v2", f"  %% behavior {spec.name}"]

    def declare(name: str, child: StateSpec, child_path: str, indent: str) -> None:
        node = _id(child_path)
        if _is_container(child):
            lines.append(f'{indent}state "{name} [{child.block}]" as {node} {{')
            machine(child, child_path, indent + "  ")
            lines.append(f"{indent}}}")
        else:
            lines.append(f'{indent}state "{name} ({child.block})" as {node}')

    def machine(state: StateSpec, path: str, indent: str) -> None:
        children = state.states
        if state.block == "concurrence":
            for i, (name, child) in enumerate(children.items()):
                child_path = f"{path}/{name}" if path else name
                if i:
                    lines.append(f"{indent}--")
                declare(name, child, child_path, indent)
                lines.append(f"{indent}[*] --> {_id(child_path)}")
            return
        for name, child in children.items():
            declare(name, child, f"{path}/{name}" if path else name, indent)
        if state.block not in ("state_machine", "sequence"):
            for name in children:
                lines.append(f"{indent}[*] --> {_id(f'{path}/{name}' if path else name)}")
            return
        first = state.params.get("initial") or next(iter(children))
        lines.append(f"{indent}[*] --> {_id(f'{path}/{first}' if path else first)}")
        for name, child in children.items():
            child_path = f"{path}/{name}" if path else name
            for outcome in child.outcomes() or ():
                target = child.transitions.get(outcome, outcome)
                src = _id(child_path)
                if target in children:
                    dst = _id(f"{path}/{target}" if path else target)
                    lines.append(f"{indent}{src} --> {dst} : {outcome}")
                else:
                    lines.append(f"{indent}{src} --> [*] : {outcome} → {target}")

    machine(spec.root, "", "  ")
    for path in sorted(lit):
        lines.append(f"  class {_id(path)} active")
    if lit:
        lines.append(f"  classDef active fill:{ACTIVE_COLOR},stroke:#333,stroke-width:2px")
    return "\n".join(lines) + "\n"

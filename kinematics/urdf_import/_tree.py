"""The URDF's link tree and the choice of the chain's ends (base and tip links)."""

from __future__ import annotations

from collections import deque
from typing import Any

from ..errors import FieldError, Loc
from ._parse import MOVING_TYPES, Srdf, UrdfJoint, UrdfRobot

__all__ = ["Tree", "chain_ends", "known_link", "listing", "movable"]


def listing(names, limit: int = 30) -> str:
    names = list(names)
    shown = ", ".join(names[:limit])
    return shown + (f", ... ({len(names)} in all)" if len(names) > limit else "") or "(none)"


class Tree:
    """Parent joints, children and a root-first order of a URDF's links; the checks that
    make it a tree (known links, one parent each, no cycle, one root)."""

    def __init__(self, robot: UrdfRobot):
        self.robot = robot
        self.parent: dict[str, UrdfJoint] = {}
        self.children: dict[str, list[UrdfJoint]] = {name: [] for name in robot.links}
        for joint in robot.joints.values():
            for end, link in (("parent", joint.parent), ("child", joint.child)):
                if link not in robot.links:
                    raise FieldError(joint.loc + (end,), f"joint '{joint.name}': unknown "
                                                         f"{end} link '{link}'")
            if joint.child in self.parent:
                first = self.parent[joint.child].name
                raise FieldError(("file", f"link[{joint.child}]"),
                                 f"link '{joint.child}' has two parent joints, '{first}' and "
                                 f"'{joint.name}': closed loops are not supported (a URDF is a "
                                 "tree)")
            self.parent[joint.child] = joint
            self.children[joint.parent].append(joint)
        roots = [name for name in robot.links if name not in self.parent]
        self.order: list[str] = []
        queue = deque(roots)
        while queue:
            name = queue.popleft()
            self.order.append(name)
            queue.extend(j.child for j in self.children[name])
        if len(self.order) < len(robot.links):
            reached = set(self.order)
            start = next(name for name in robot.links if name not in reached)
            self._cycle(start)
        if len(roots) > 1:
            raise FieldError(("file", f"link[{roots[1]}]"),
                             f"link '{roots[1]}' is not connected to the root link "
                             f"'{roots[0]}': a URDF has one root; links without a parent "
                             f"joint: {listing(roots)}")
        self.root = roots[0]

    def _cycle(self, start: str) -> None:
        seen: list[str] = []
        name = start
        while name not in seen:
            seen.append(name)
            name = self.parent[name].parent
        cycle = seen[seen.index(name):]
        cycle.reverse()  # parent to child
        text = " -> ".join([*cycle, cycle[0]])
        raise FieldError(("file", f"link[{cycle[0]}]"),
                         f"the joints form a cycle through link '{cycle[0]}': {text}")

    def below(self, name: str) -> list[str]:
        """``name`` and every link below it, parents first."""
        out, queue = [], deque([name])
        while queue:
            link = queue.popleft()
            out.append(link)
            queue.extend(j.child for j in self.children[link])
        return out

    def path(self, base: str, tip: str) -> list[UrdfJoint]:
        """The joints from ``base`` down to ``tip``."""
        joints = []
        name = tip
        while name != base:
            joint = self.parent.get(name)
            if joint is None:
                raise FieldError(("tip_link",), f"link '{tip}' is not below base_link '{base}'; "
                                                f"links below it: "
                                                f"{listing(self.below(base)[1:])}")
            joints.append(joint)
            name = joint.parent
        joints.reverse()
        return joints


def movable(joint: UrdfJoint) -> bool:
    return joint.type in MOVING_TYPES and joint.mimic is None


def default_tip(tree: Tree, base: str) -> str:
    """The child link of the last movable joint, when the movable (non-mimic) joints below
    ``base`` form one chain."""
    order = tree.below(base)
    moves_below: dict[str, bool] = {}
    ends: list[UrdfJoint] = []
    for name in reversed(order):  # children before parents
        below = False
        for joint in tree.children[name]:
            child_moves = moves_below[joint.child]
            if movable(joint) and not child_moves:
                ends.append(joint)
            below = below or child_moves or movable(joint)
        moves_below[name] = below
    if not ends:
        raise FieldError(("tip_link",), f"no movable joint below base_link '{base}'")
    if len(ends) > 1:
        tips = sorted((j.child for j in ends), key=order.index)
        raise FieldError(("tip_link",), f"the movable joints below '{base}' end in "
                                        f"{len(ends)} chains: give tip_link (or an SRDF "
                                        f"group); candidates: {listing(tips)}")
    return ends[0].child


def known_link(robot: UrdfRobot, name: Any, loc: Loc, what: str) -> str:
    if not isinstance(name, str) or name not in robot.links:
        raise FieldError(loc, f"unknown {what} {name!r}; links: {listing(robot.links)}")
    return name


def chain_ends(tree: Tree, robot: UrdfRobot, srdf: Srdf | None, base_link: str | None,
                tip_link: str | None, group: str | None) -> tuple[str, str]:
    def from_group(name: str) -> tuple[str, str]:
        chains = srdf.groups[name]
        if len(chains) != 1:
            with_chain = [g for g, c in srdf.groups.items() if len(c) == 1]
            raise FieldError(("group",), f"group '{name}' has {len(chains)} <chain> elements; "
                                         f"one is needed; groups with one chain: "
                                         f"{listing(with_chain)}")
        base, tip, loc = chains[0]
        return (known_link(robot, base, loc + ("base_link",), "SRDF chain base_link"),
                known_link(robot, tip, loc + ("tip_link",), "SRDF chain tip_link"))

    if group is not None:
        if srdf is None:
            raise FieldError(("group",), "there is no SRDF: give srdf, or put one .srdf file "
                                         "in the archive")
        if base_link is not None or tip_link is not None:
            raise FieldError(("group",), "give either group or base_link/tip_link, not both")
        if not isinstance(group, str) or group not in srdf.groups:
            raise FieldError(("group",), f"unknown group {group!r}; the SRDF's groups: "
                                         f"{listing(srdf.groups)}")
        return from_group(group)
    if base_link is None and tip_link is None and srdf is not None:
        with_chain = [g for g, c in srdf.groups.items() if len(c) == 1]
        if len(with_chain) == 1:
            return from_group(with_chain[0])
    base = tree.root if base_link is None else known_link(robot, base_link, ("base_link",),
                                                           "base_link")
    if tip_link is None:
        return base, default_tip(tree, base)
    return base, known_link(robot, tip_link, ("tip_link",), "tip_link")

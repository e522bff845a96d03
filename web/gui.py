"""The viewer's control panel: viser GUI elements and the text they show.

One panel on ``server.gui``, shared by every browser tab: the scene is shared, so the
controls that drive it are too (a slider moved in one tab moves in the others). Callbacks
are wired by ``web.viewer.Viewer``; this module only builds elements and formats text.

Joint values are shown in degrees for revolute joints and millimetres for prismatic ones
(``to_display``/``from_display``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np

from kinematics.model import RobotModel
from kinematics.workspace import MAX_SAMPLES

from .cycles import CYCLE_KINDS, StoredPlan
from .scene import CylinderDrawing
from .text import code, plain

__all__ = [
    "ControlPanel",
    "to_display",
    "from_display",
    "joint_label",
    "cylinder_table",
    "REVOLUTE_STEP_DEG",
    "PRISMATIC_STEP_MM",
    "DEFAULT_SAMPLES",
    "MIN_GUI_SAMPLES",
    "MAX_GUI_SAMPLES",
]

#: Slider steps: one arrow-key press moves a joint by this much.
REVOLUTE_STEP_DEG = 0.5
PRISMATIC_STEP_MM = 1.0
#: Default Monte Carlo samples of the workspace button (the papers' 30,000), and the range it
#: offers: at most what one synchronous ``POST /robots/{id}/workspace`` call may sample.
DEFAULT_SAMPLES = 30_000
MIN_GUI_SAMPLES = 100
MAX_GUI_SAMPLES = MAX_SAMPLES

COLLISION_HINT = ("Show the balls the collision checker uses for the robot: sphere trees on an "
                  "imported robot's collision geometry, balls along a D-H robot's link "
                  "capsules")
NO_SCENE = "No scene shown: `POST /viewer/show {\"scene\": id}`."
GOAL_HINT = ("Keep the arm's configuration as the goal of the next plan (move it there with the "
             "sliders or the gizmo first)")
PLAN_HINT = ("Plan a collision-free motion from the arm's configuration to the kept goal, in "
             "the scene shown (a motion job); the answer plays at once")
#: What each work-cycle button starts (a whole job of its kind on the robot's stored plan).
CYCLE_HINTS = {
    "round": "Plan the jumbo's whole drilling round on its stored drill plan (a round job)",
    "pallet": "Plan the palletizing cycle of the robot's stored pallet (a pallet job)",
    "piles": "Plan the pile driver's stored pile plan: set-ups, order, times (a piles job)",
}
NO_GOAL = ("Move the arm to a goal, press **Set goal here**, move it to the start, then "
           "**Plan**.")

HELP = ("Pick a robot, move the joints, or drag the gizmo at the tool (IK). "
        "`POST /viewer/show` shows robots, finished jobs and scenes here.")


def to_display(model: RobotModel, q) -> list[float]:
    """Joint values as the sliders show them: degrees (revolute), mm (prismatic)."""
    q = np.asarray(q, dtype=float)
    return [math.degrees(v) if j.revolute else float(v) for j, v in zip(model.joints, q)]


def from_display(model: RobotModel, values: Sequence[float]) -> np.ndarray:
    """Inverse of ``to_display``: ``(dof,)`` rad / mm."""
    return np.array([math.radians(v) if j.revolute else float(v)
                     for j, v in zip(model.joints, values)])


def joint_label(model: RobotModel, i: int) -> str:
    j = model.joints[i]
    return f"{i + 1} {j.name} [{'°' if j.revolute else 'mm'}]"


def cylinder_table(cylinders: Sequence[CylinderDrawing]) -> str:
    """Markdown table of cylinder lengths and strokes (mm): the stroke (the current extension,
    as the API's ``stroke``) and the full travel in one cell, ``121.3 / 231.4``, so the two
    numbers never run together in a narrow panel."""
    if not cylinders:
        return ""
    rows = ["| cylinder | joint | length mm | stroke / travel mm |", "|---|---|--:|--:|"]
    for c in cylinders:
        flag = "" if c.within_stroke else " ⚠ outside its travel"
        rows.append(f"| {plain(c.name)} | {plain(c.joint)} | {c.length:.1f} | "
                    f"{c.stroke:.1f} / {c.max_length - c.min_length:.1f}{flag} |")
    return "\n".join(rows)


class ControlPanel:
    """Every GUI element of the viewer (on a shared ``GuiApi``)."""

    def __init__(self, gui: Any, robot_options: Sequence[str], current: str) -> None:
        self.gui = gui
        self.help = gui.add_markdown(HELP, order=0)
        self.robot = gui.add_dropdown("Robot", options=tuple(robot_options),
                                      initial_value=current, order=1)
        self.arm = gui.add_dropdown("Arm", options=("-",), visible=False, order=2,
                                    hint="The arm of the rig that the sliders and IK drive")
        self.collision = gui.add_checkbox("Collision model", False, order=2.5,
                                          hint=COLLISION_HINT)
        self.collision_info = gui.add_markdown("", order=2.6, visible=False)
        self._joints_folder: Any = None
        self.sliders: list[Any] = []
        with gui.add_folder("Hydraulic cylinders", order=4, visible=False) as folder:
            self.cylinders_folder = folder
            self.cylinders = gui.add_markdown("")
        with gui.add_folder("IK: drag the gizmo at the tool", order=5):
            self.ik = gui.add_markdown("The arm follows the gizmo where IK reaches it.")
        with gui.add_folder("Workspace", order=6):
            self.samples = gui.add_number("Samples", DEFAULT_SAMPLES, min=MIN_GUI_SAMPLES,
                                          max=MAX_GUI_SAMPLES, step=1000)
            self.run_workspace = gui.add_button("Run workspace", icon=None)
            self.progress = gui.add_progress_bar(0.0, visible=False, animated=True)
            self.workspace = gui.add_markdown("")
        with gui.add_folder("Work cycle", order=6.5):
            self.cycle_plan = gui.add_markdown("")
            self.run_cycle = {kind: gui.add_button(f"Run {kind}", visible=False,
                                                   hint=CYCLE_HINTS[kind])
                              for kind in CYCLE_KINDS}
            self.cycle_progress = gui.add_progress_bar(0.0, visible=False, animated=True)
            self.cycle = gui.add_markdown("")
        with gui.add_folder("Plan", order=7):
            self.set_goal = gui.add_button("Set goal here", hint=GOAL_HINT)
            self.run_plan = gui.add_button("Plan", disabled=True, hint=PLAN_HINT)
            self.motion = gui.add_markdown(NO_GOAL)
            self.plan = gui.add_markdown("No plan shown: plan one above, or "
                                         "`POST /viewer/show {\"job\": id}`.")
            self.time = gui.add_slider("Time [s]", min=0.0, max=1.0, step=0.01,
                                       initial_value=0.0, disabled=True)
            self.play = gui.add_button("Play", disabled=True)
            self.speed = gui.add_slider("Speed ×", min=0.1, max=10.0, step=0.1,
                                        initial_value=1.0)
        with gui.add_folder("Scene", order=8):
            self.scene = gui.add_markdown(NO_SCENE)

    # joints -----------------------------------------------------------------------------
    def set_joints(self, model: RobotModel, q, on_change: Callable[[int, Any], None]) -> None:
        """Rebuild the joint sliders for ``model`` at ``q``; ``on_change(i, event)`` is called
        when a browser moves slider ``i``."""
        if self._joints_folder is not None:
            self._joints_folder.remove()
        self.sliders = []
        values = to_display(model, q)
        with self.gui.add_folder(f"Joints of {model.id}", order=3) as folder:
            self._joints_folder = folder
            for i, j in enumerate(model.joints):
                lo, hi = (math.degrees(j.lower), math.degrees(j.upper)) if j.revolute \
                    else (j.lower, j.upper)
                step = REVOLUTE_STEP_DEG if j.revolute else PRISMATIC_STEP_MM
                s = self.gui.add_slider(joint_label(model, i), min=round(lo, 3),
                                        max=round(hi, 3), step=step,
                                        initial_value=float(np.clip(values[i], lo, hi)))
                s.on_update(lambda event, i=i: on_change(i, event))
                self.sliders.append(s)

    def show_q(self, model: RobotModel, q) -> None:
        """Put the sliders at ``q`` (programmatic: the viewer's callbacks ignore it)."""
        for s, v in zip(self.sliders, to_display(model, q)):
            v = float(np.clip(v, s.min, s.max))
            if abs(s.value - v) > 1e-9:
                s.value = v

    def slider_q(self, model: RobotModel) -> np.ndarray:
        """The configuration the sliders show ``(dof,)``."""
        return from_display(model, [s.value for s in self.sliders])

    def show_collision(self, text: str) -> None:
        """The line under the collision checkbox (hidden when empty)."""
        self.collision_info.visible = bool(text)
        if self.collision_info.content != text:
            self.collision_info.content = text

    def show_cycle_plan(self, key: str, plan: StoredPlan | None,
                        plans: Mapping[str, StoredPlan]) -> None:
        """The work-cycle folder for robot or rig ``key``: the button of its stored ``plan``
        (none without one) and what the plan is, or which robots have one."""
        for kind, button in self.run_cycle.items():
            button.visible = plan is not None and plan.kind == kind
        if plan is not None:
            text = f"Stored plan of {code(key)}: {plain(plan.title)}."
        elif plans:
            have = ", ".join(f"{code(k)} ({plain(p.kind)})" for k, p in plans.items())
            text = f"No stored plan for {code(key)}. Work cycles run for {have}."
        else:
            text = "No stored plans on this service."
        if self.cycle_plan.content != text:
            self.cycle_plan.content = text

    def show_cylinders(self, cylinders: Sequence[CylinderDrawing]) -> None:
        self.cylinders_folder.visible = bool(cylinders)
        text = cylinder_table(cylinders)
        if self.cylinders.content != text:
            self.cylinders.content = text

    # plan playback ----------------------------------------------------------------------
    def set_playback(self, duration: float) -> None:
        """Enable the time slider over ``[0, duration]`` s (disabled when 0)."""
        has = duration > 0
        self.time.disabled = not has
        self.play.disabled = not has
        # A round step (0.01 s for a 14 s motion) and the end rounded up to it: the panel
        # shows "14.07", not "14.066508".
        step = 10.0 ** math.floor(math.log10(max(duration / 500.0, 1e-3)))
        self.time.step = step
        self.time.max = max(round(math.ceil(duration / step - 1e-9) * step, 6), step)
        self.time.value = 0.0
        self.play.label = "Play"

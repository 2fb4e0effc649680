"""Drive Lights: the original program's keys in the 3D View, a modal operator (Shift+Ctrl+L, or the Lights panel's
button). 1-8 pick the SH light, Q/A and W/E step θ and φ (Shift: fine steps), a left-button drag turns the active
light, F1/F2 switch the PRT display off/on, T the albedo texture, N and L the overlays; Enter or a left click keeps
the change, Esc or a right click puts back the aims, active light and switches it started from.

The keys are tables and the state is a LightDriver that takes one event at a time, so tests drive the modal step
with stand-in events; the operator only adds the header text and the modal handler.
"""

import math

import bpy

from ..blender import aiming

STEP = math.radians(5.0)
FINE_STEP = math.radians(1.0)
DRAG_STEP = math.radians(0.5)  # per pixel
FINE_DRAG_STEP = math.radians(0.1)
CLICK_DISTANCE = 3  # pixels: a left press and release closer than this is a click (keep), farther a drag (turn)

LIGHT_KEYS = {key: index for index, key in enumerate(("ONE", "TWO", "THREE", "FOUR", "FIVE", "SIX", "SEVEN",
                                                      "EIGHT"))}
ANGLE_KEYS = {"Q": (-1, 0), "A": (1, 0), "W": (0, -1), "E": (0, 1)}  # (dθ, dφ) in steps: Q raises the light
SWITCH_KEYS = {"F1": ("show_prt", False), "F2": ("show_prt", True), "T": ("use_albedo", None),
               "N": ("show_normals", None), "L": ("show_light_directions", None)}  # None: toggle
SWITCHES = tuple(dict.fromkeys(name for name, _ in SWITCH_KEYS.values()))
CONFIRM_KEYS = {"RET", "NUMPAD_ENTER"}
CANCEL_KEYS = {"ESC", "RIGHTMOUSE"}
NAVIGATION = {"MIDDLEMOUSE", "WHEELUPMOUSE", "WHEELDOWNMOUSE", "TRACKPADPAN", "TRACKPADZOOM", "MOUSEROTATE",
              "MOUSESMARTZOOM", "NDOF_MOTION"}  # passed to the viewport, so the view still turns and zooms
HELP = ("1-8 light, Q/A θ, W/E φ (Shift fine), drag turn, F1/F2 PRT off/on, T albedo, N normals, L light lines, "
        "Enter keep, Esc restore")

KEYMAP = ("3D View", "VIEW_3D", "L", {"ctrl": True, "shift": True})  # Shift+Ctrl+L is free in Blender's keymap
_keymap_items = []  # (keymap, item) pairs added at register


class LightDriver:
    """The operator's state: what Esc puts back, the held left button, the last mouse position and sentence."""

    def __init__(self, scene, mouse):
        self.scene = scene
        self.started = aiming.Aims(scene, SWITCHES)
        self.mouse = mouse
        self.pressed_at = None  # where the left button went down, while it is held
        self.said = ""

    def step(self, event) -> set:
        """One event: {'RUNNING_MODAL'}, {'PASS_THROUGH'} (navigation), {'FINISHED'} (kept) or {'CANCELLED'}
        (everything put back)."""
        if event.type in NAVIGATION:
            return {"PASS_THROUGH"}
        if event.type == "MOUSEMOVE":
            return self._move(event)
        if event.type == "LEFTMOUSE":
            return self._left(event)
        if event.value != "PRESS":
            return {"RUNNING_MODAL"}
        if event.type in CONFIRM_KEYS:
            return {"FINISHED"}
        if event.type in CANCEL_KEYS:
            self.started.restore()
            return {"CANCELLED"}
        self.said = ""
        if event.type in LIGHT_KEYS:
            self._pick(LIGHT_KEYS[event.type])
        elif event.type in ANGLE_KEYS:
            d_theta, d_phi = ANGLE_KEYS[event.type]
            step = FINE_STEP if event.shift else STEP
            self._turn(d_theta * step, d_phi * step)
        elif event.type in SWITCH_KEYS:
            name, value = SWITCH_KEYS[event.type]
            display = self.scene.prt_display
            setattr(display, name, not getattr(display, name) if value is None else value)
        return {"RUNNING_MODAL"}

    def header(self) -> str:
        lights = self.scene.prt_lights
        active = self.active()
        aim = aiming.aim_text(lights[active])
        said = f" ({self.said})" if self.said else ""
        return f"Drive Lights: light {active + 1} of {len(lights)}, {aim}{said}. {HELP}"

    def active(self) -> int:
        return min(self.scene.prt_active_light, len(self.scene.prt_lights) - 1)

    def _pick(self, index):
        count = len(self.scene.prt_lights)
        if index < count:
            self.scene.prt_active_light = index
        else:
            self.said = f"no light {index + 1}: the scene has {count}"

    def _turn(self, d_theta, d_phi):
        self.said = aiming.turn(self.scene, self.active(), d_theta, d_phi) or ""

    def _left(self, event):
        if event.value == "PRESS":
            self.pressed_at = self.mouse = (event.mouse_x, event.mouse_y)
            return {"RUNNING_MODAL"}
        if event.value == "RELEASE" and self.pressed_at is not None:
            moved = math.dist(self.pressed_at, (event.mouse_x, event.mouse_y))
            self.pressed_at = None
            if moved < CLICK_DISTANCE:
                return {"FINISHED"}
        return {"RUNNING_MODAL"}

    def _move(self, event):
        """While the left button is held, a drag turns the active light: right turns φ up, up raises it (θ down)."""
        if self.pressed_at is None:
            return {"PASS_THROUGH"}
        step = FINE_DRAG_STEP if event.shift else DRAG_STEP
        dx, dy = event.mouse_x - self.mouse[0], event.mouse_y - self.mouse[1]
        self.mouse = (event.mouse_x, event.mouse_y)
        if dx or dy:
            self._turn(-dy * step, dx * step)
        return {"RUNNING_MODAL"}


class PRT_OT_drive_lights(bpy.types.Operator):
    """Turn the SH lights from the keyboard and mouse, as the original program did: 1-8 pick a light, Q/A and W/E
    step θ and φ, a drag turns it; Enter keeps, Esc puts everything back"""
    bl_idname = "prt.drive_lights"
    bl_label = "Drive Lights"
    bl_options = {"UNDO"}  # kept changes are one undo step

    @classmethod
    def poll(cls, context):
        return context.area is not None and context.area.type == "VIEW_3D" and len(context.scene.prt_lights) > 0

    def invoke(self, context, event):
        self.driver = LightDriver(context.scene, (event.mouse_x, event.mouse_y))
        context.window_manager.modal_handler_add(self)
        context.area.header_text_set(self.driver.header())
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        outcome = self.driver.step(event)
        context.area.header_text_set(None if outcome & {"FINISHED", "CANCELLED"} else self.driver.header())
        context.area.tag_redraw()  # the overlays and the header
        return outcome


def register_keymap(keyconfigs, background: bool):
    """Shift+Ctrl+L in the 3D View, where Blender has an add-on keyconfig; never in background mode, which has no
    keyboard (the bpy module has an add-on keyconfig even there)."""
    if background or keyconfigs.addon is None:
        return
    name, space, key, modifiers = KEYMAP
    keymap = keyconfigs.addon.keymaps.new(name=name, space_type=space)
    _keymap_items.append((keymap, keymap.keymap_items.new(PRT_OT_drive_lights.bl_idname, key, "PRESS",
                                                          **modifiers)))


def unregister_keymap():
    for keymap, item in _keymap_items:
        keymap.keymap_items.remove(item)
    _keymap_items.clear()


register_class, unregister_class = bpy.utils.register_classes_factory((PRT_OT_drive_lights,))


def register():
    register_class()
    register_keymap(bpy.context.window_manager.keyconfigs, bpy.app.background)


def unregister():
    unregister_keymap()
    unregister_class()

"""Drive Lights, the modal operator with the original program's keys, driven with stand-in events and context
(with the bpy module, timers never fire and INVOKE_DEFAULT runs execute(), so its invoke and modal are called
directly). The operator and its keymap belong to the installed add-on, so its module is used."""

from dataclasses import dataclass
import importlib
import math
from types import SimpleNamespace

import bpy
import pytest

from conftest import FakeLayout, add_light

SETTINGS = ("theta", "phi", "angular_radius", "sun_object", "rotation")
SWITCHES = ("show_prt", "use_albedo", "show_normals", "show_light_directions")


@dataclass
class Event:
    type: str
    value: str = "PRESS"
    shift: bool = False
    mouse_x: int = 100
    mouse_y: int = 100


class Area:
    """Records the header texts the operator sets (None clears it)."""
    type = "VIEW_3D"

    def __init__(self):
        self.headers = []

    def header_text_set(self, text):
        self.headers.append(text)

    def tag_redraw(self):
        pass


@pytest.fixture
def drive(addon):
    return importlib.import_module(f"{addon}.prt_addon.ui.drive")


@pytest.fixture
def lights(empty_scene):
    """Three suns; the first is active."""
    suns = [add_light(theta=math.radians(35.0 + 10 * i), phi=math.radians(-60.0 + 30 * i)) for i in range(3)]
    empty_scene.prt_active_light = 0
    return suns


class Session:
    """The operator invoked on stand-ins, as Blender calls it; `press` sends events to its modal step."""

    def __init__(self, drive):
        self.operator = SimpleNamespace()
        self.area = Area()
        self.handlers = []
        self.context = SimpleNamespace(scene=bpy.context.scene, area=self.area,
                                       window_manager=SimpleNamespace(modal_handler_add=self.handlers.append))
        self.drive = drive
        assert drive.PRT_OT_drive_lights.invoke(self.operator, self.context, Event("L")) == {"RUNNING_MODAL"}
        assert self.handlers == [self.operator]

    def send(self, *events):
        return [self.drive.PRT_OT_drive_lights.modal(self.operator, self.context, event) for event in events]

    def press(self, *keys, shift=False):
        return self.send(*(Event(key, shift=shift) for key in keys))

    @property
    def header(self):
        return self.area.headers[-1]


@pytest.fixture
def session(drive, lights):
    return Session(drive)


def degrees(light):
    return pytest.approx(math.degrees(light.theta), abs=1e-4), pytest.approx(math.degrees(light.phi), abs=1e-4)


def aims(scene):
    return ([{name: (tuple(getattr(light, name)) if name == "rotation" else getattr(light, name))
              for name in SETTINGS} for light in scene.prt_lights],
            scene.prt_active_light, {name: getattr(scene.prt_display, name) for name in SWITCHES})


def test_q_a_step_theta_and_w_e_step_phi_by_5_degrees_or_1_with_shift(session, lights):
    sun = lights[0]
    assert session.press("Q") == [{"RUNNING_MODAL"}]
    assert (math.degrees(sun.theta), math.degrees(sun.phi)) == degrees(sun) == (30.0, -60.0)
    session.press("A", "A")
    assert degrees(sun) == (40.0, -60.0)
    session.press("A", shift=True)
    assert degrees(sun) == (41.0, -60.0)
    session.press("W")
    assert degrees(sun) == (41.0, -65.0)
    session.press("E", shift=True)
    assert degrees(sun) == (41.0, -64.0)
    assert "light 1 of 3" in session.header and "θ 41.0°, φ -64.0°" in session.header
    assert [degrees(other) for other in lights[1:]] == [(45.0, -30.0), (55.0, 0.0)]  # only the active one turns


def test_theta_stops_at_the_zenith_and_phi_wraps_around(session, lights):
    lights[0].theta, lights[0].phi = math.radians(3.0), math.radians(178.0)
    session.press("Q", "E")
    assert degrees(lights[0]) == (0.0, -177.0)


def test_number_keys_pick_the_light_and_a_key_beyond_the_count_says_so(session, lights, empty_scene):
    session.press("TWO")
    assert empty_scene.prt_active_light == 1 and "light 2 of 3" in session.header
    session.press("EIGHT")
    assert empty_scene.prt_active_light == 1
    assert "no light 8: the scene has 3" in session.header
    session.press("Q")
    assert degrees(lights[1]) == (40.0, -30.0) and degrees(lights[0]) == (35.0, -60.0)
    assert "no light 8" not in session.header


def test_f1_f2_t_n_l_switch_the_display_and_overlays(session, empty_scene):
    display = empty_scene.prt_display
    before = {name: getattr(display, name) for name in SWITCHES}
    session.press("F2")
    assert display.show_prt
    session.press("F2")
    assert display.show_prt  # F2 is "PRT on", not a toggle
    session.press("F1")
    assert not display.show_prt
    session.press("T", "N", "L")
    assert (display.use_albedo, display.show_normals, display.show_light_directions) == (
        not before["use_albedo"], not before["show_normals"], not before["show_light_directions"])
    session.send(Event("T", value="RELEASE"))  # a key acts when pressed, not again when released
    assert display.use_albedo == (not before["use_albedo"])
    session.press("T")
    assert display.use_albedo == before["use_albedo"]


def test_a_drag_turns_the_active_sun_and_a_move_without_the_button_does_not(session, lights):
    sun = lights[0]
    assert session.send(Event("MOUSEMOVE", mouse_x=300, mouse_y=300)) == [{"PASS_THROUGH"}]
    assert degrees(sun) == (35.0, -60.0)
    outcomes = session.send(Event("LEFTMOUSE", mouse_x=100, mouse_y=100),
                            Event("MOUSEMOVE", mouse_x=120, mouse_y=90),   # right 20 px, down 10 px
                            Event("MOUSEMOVE", mouse_x=130, mouse_y=90, shift=True),
                            Event("LEFTMOUSE", value="RELEASE", mouse_x=130, mouse_y=90))
    assert outcomes == [{"RUNNING_MODAL"}] * 4  # released far from where it was pressed: a drag, not a click
    assert degrees(sun) == (35.0 + 10 * 0.5, -60.0 + 20 * 0.5 + 10 * 0.1)


@pytest.mark.parametrize("confirm", [[Event("RET")], [Event("LEFTMOUSE"), Event("LEFTMOUSE", value="RELEASE")]],
                         ids=["enter", "left click"])
def test_enter_or_a_left_click_keeps_the_change(session, lights, empty_scene, confirm):
    session.press("TWO", "Q", "F2", "N")
    kept = aims(empty_scene)
    assert session.send(*confirm)[-1] == {"FINISHED"}
    assert aims(empty_scene) == kept and degrees(lights[1]) == (40.0, -30.0)
    assert session.header is None


@pytest.mark.parametrize("cancel", ["ESC", "RIGHTMOUSE"])
def test_esc_or_a_right_click_puts_back_exactly_what_it_started_from(drive, empty_scene, cancel):
    sun_object = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    empty_scene.collection.objects.link(sun_object)
    sun_object.rotation_euler = (0.4, 0.2, 0.3)
    add_light(theta=0.61, phi=-1.05, angular_radius=0.03)
    add_light(sun_object=sun_object)
    add_light("ENVIRONMENT", rotation=(0.1, 0.2, 0.3))
    add_light("SKY")
    empty_scene.prt_active_light = 0
    empty_scene.prt_display.use_albedo = False
    before = aims(empty_scene)
    session = Session(drive)
    session.press("Q", "W", "F2", "T", "N", "L")
    session.send(Event("LEFTMOUSE"), Event("MOUSEMOVE", mouse_x=140, mouse_y=70),
                 Event("LEFTMOUSE", value="RELEASE", mouse_x=140, mouse_y=70))
    for key in ("TWO", "THREE", "FOUR"):
        session.press(key, "A", "E")
    assert empty_scene.prt_lights[1].sun_object is None  # turning a followed sun let its object go
    changed = aims(empty_scene)
    assert [changed[0][i] != before[0][i] for i in range(3)] == [True, True, True]
    assert changed[1:] != before[1:]
    assert session.press(cancel) == [{"CANCELLED"}]
    assert aims(empty_scene) == before
    assert session.header is None


def test_an_environment_turns_about_z_with_w_e_and_about_y_with_q_a(session, empty_scene):
    environment = add_light("ENVIRONMENT")
    session.press("FOUR", "E")
    assert tuple(math.degrees(a) for a in environment.rotation) == pytest.approx((0.0, 0.0, 5.0), abs=1e-4)
    assert "environment 'Environment': rotation X 0.0° Y 0.0° Z 5.0°" in session.header
    session.press("Q")  # R = Ry(−5°)·Rz(5°): what came from the zenith comes from R·z, tilted as a sun at φ 0 by Q
    zenith_light = environment.rotation.to_matrix().col[2]
    assert tuple(zenith_light) == pytest.approx((-math.sin(math.radians(5)), 0.0, math.cos(math.radians(5))),
                                                abs=1e-6)


def test_a_followed_sun_lets_its_object_go_and_a_sky_has_nothing_to_turn(session, empty_scene):
    sun_object = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", "SUN"))
    empty_scene.collection.objects.link(sun_object)
    followed = add_light(sun_object=sun_object)
    add_light("SKY")
    session.press("FOUR")
    assert "follows 'Sun'" in session.header
    session.press("W")
    assert followed.sun_object is None and "no longer follows 'Sun'" in session.header
    assert degrees(followed) == (0.0, -5.0)  # the object's direction, straight down its −Z: the zenith
    session.press("FIVE", "Q")
    assert "is a sky, the same from every direction: nothing to turn" in session.header


def test_navigation_passes_through_and_other_keys_are_swallowed(session, lights, empty_scene):
    before = aims(empty_scene)
    assert session.press("MIDDLEMOUSE", "WHEELUPMOUSE") == [{"PASS_THROUGH"}] * 2
    assert session.press("X", "DEL") == [{"RUNNING_MODAL"}] * 2
    assert aims(empty_scene) == before


def test_poll_wants_a_3d_view_and_a_light(drive, empty_scene):
    poll = drive.PRT_OT_drive_lights.poll
    view = SimpleNamespace(scene=empty_scene, area=Area())
    assert not poll(view)
    add_light()
    assert poll(view)
    assert not poll(SimpleNamespace(scene=empty_scene, area=None))


def keymap_items(keyconfig, idname="prt.drive_lights"):
    return [item for keymap in keyconfig.keymaps for item in keymap.keymap_items if item.idname == idname]


def test_keymap_is_not_registered_in_background_mode(drive):
    """The bpy module has an add-on keyconfig even in background mode: the add-on must not use it there."""
    keyconfigs = bpy.context.window_manager.keyconfigs
    assert bpy.app.background and keyconfigs.addon is not None
    assert keymap_items(keyconfigs.addon) == [] and drive._keymap_items == []
    drive.register_keymap(keyconfigs, background=True)
    assert keymap_items(keyconfigs.addon) == []
    drive.register_keymap(SimpleNamespace(addon=None), background=False)  # a Blender without one: nothing
    assert drive._keymap_items == []


def test_keymap_with_a_display_is_shift_ctrl_l_in_the_3d_view_and_goes_at_unregister(drive):
    keyconfigs = bpy.context.window_manager.keyconfigs
    drive.register_keymap(keyconfigs, background=False)
    try:
        (item,) = keymap_items(keyconfigs.addon)
        (keymap, _), = drive._keymap_items
        assert (keymap.name, keymap.space_type) == ("3D View", "VIEW_3D")
        assert (item.type, item.value, item.ctrl, item.shift, item.alt) == ("L", "PRESS", True, True, False)
    finally:
        drive.unregister_keymap()
    assert keymap_items(keyconfigs.addon) == [] and drive._keymap_items == []


def test_lights_panel_has_the_drive_lights_button(empty_scene, lights):
    operators = []

    class Layout(FakeLayout):
        def operator(self, idname, **kwargs):
            super().operator(idname, **kwargs)
            operators.append(idname)

    panel = bpy.types.PRT_PT_lights
    panel.draw(SimpleNamespace(layout=Layout([]), _draw_light=panel._draw_light), bpy.context)
    assert "prt.drive_lights" in operators

"""The interactive viewer: one or two runs in a browser through viser (a web client served from Python).

The scene holds, per run, its visual Gaussians as splats (the frame of the time slider), its physical particles
coloured by speed (off until toggled), its cameras as frusta showing their video's frame at that time (green
input, orange synthesised, red held-out), the source disk, the obstacles (gray declared, cyan found, magenta an
interaction's), the static layer and the volume's box. A second run stands beside the first (side by side) or in
its place (toggle). Frames are read when shown; videos are decoded in a background thread, so a long run opens as
fast as its first frame. viser is imported only here (the ``[view]`` extra).
"""
from __future__ import annotations

import logging
import socket
import threading
import time
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from .content import ROLE_COLORS, box_segments, disk_mesh, frustum_pose, gaussian_splats, speed_colors, state_splats
from .sources import Body, RunContent, Thumbnails

log = logging.getLogger("fluidnexus")

INSTALL = "pip install 'fluidnexus[view]'"
BODY_COLORS = {"declared": (150, 150, 150), "found": (40, 200, 220), "interaction": (220, 60, 200)}
SOURCE_COLOR = (255, 140, 0)
LAYOUTS = ("side by side", "toggle")


def require_viser():
    """The viser module, or an InputError that says how to install it."""
    try:
        import viser
    except ImportError:
        raise InputError(None, "view", f"needs viser, which is not installed: {INSTALL}") from None
    return viser


def check_port(host: str, port: int) -> None:
    """Raise InputError when ``host`` does not resolve or ``port`` cannot be bound there (in use, privileged)."""
    if not 0 < port < 65536:
        raise InputError(None, "--port", f"must be in 1..65535, got {port}")
    try:
        family, kind, proto, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
    except socket.gaierror as err:
        raise InputError(None, "--host", f"{host!r} does not resolve ({err.strerror})") from None
    with socket.socket(family, kind, proto) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as the server binds
        try:
            probe.bind(address)
        except OSError as err:
            raise InputError(None, "--port", f"cannot listen on {host}:{port} ({err.strerror}); "
                                             "pick another --port") from None


PARTS = ("frusta", "scenery", "static")  # scene-tree groups of a run that the panel shows or hides


@dataclass
class RunNodes:
    """The scene-tree handles of one run: its group (placed beside or over the other run), the groups of its
    parts, the frusta by camera name, and the smoke and particles of the shown frame."""

    group: object
    parts: dict
    offset: np.ndarray
    smoke: object | None = None
    particles: object | None = None
    frusta: dict | None = None


class Viewer:
    """A viser scene and control panel over ``runs`` (one or two :class:`RunContent`).

    Attributes:
        server: the ``viser.ViserServer``.
        times: every frame index of the runs, in order (the time slider's range).
        frame: the slider (``frame.value`` sets the shown frame, from the page or from Python).
    """

    def __init__(self, server, runs: list[RunContent]):
        self.server = server
        self.runs = runs
        self.times = sorted(set().union(*(r.frames for r in runs)))
        self.shown: int | None = None
        self._lock = threading.RLock()
        self._stop = threading.Event()
        scene = runs[0].scene
        self.lo, self.hi = self._extent(runs[0])
        self.size = float(np.max(self.hi - self.lo))
        self.marks = [r.cameras() for r in runs]
        self.static = [None] * len(runs)  # the static layers' splat handles, once read
        self.static_loaded = threading.Event()
        self.thumbnails = [Thumbnails(m, on_ready=self._thumbnail_ready) for m in self.marks]
        server.scene.set_up_direction("+y")
        server.scene.set_background_image(np.zeros((8, 8, 3), np.uint8))
        server.gui.configure_theme(dark_mode=True, show_share_button=False)
        center = 0.5 * (self.lo + self.hi)
        inputs = [m for m in self.marks[0] if m.role == "input"]
        toward = inputs[0].camera.center - center if inputs else np.array([0.0, 0.0, 1.0])
        toward = np.array([toward[0], 0.0, toward[2]]) / max(np.hypot(toward[0], toward[2]), 1e-9)
        eye = center + self.size * (2.2 * toward + np.array([0.0, 0.6, 0.0]))  # the first input camera's side, above
        server.initial_camera.position = tuple(eye)
        server.initial_camera.look_at = tuple(center)
        server.initial_camera.up = (0.0, 1.0, 0.0)
        self.top_speed = self._top_speed()
        self.nodes = [RunNodes(server.scene.add_frame(f"/run{i}", show_axes=False),
                               {p: server.scene.add_frame(f"/run{i}/{p}", show_axes=False) for p in PARTS},
                               np.zeros(3)) for i in range(len(runs))]
        self._build_gui(scene.fps)
        for i, run in enumerate(runs):
            self._add_fixed(i, run)
        self._place_runs()
        self.show(self.times[0])
        for thumbs in self.thumbnails:
            thumbs.start()
        threading.Thread(target=self._load_static_layers, name="viewer-static", daemon=True).start()
        threading.Thread(target=self._play_loop, name="viewer-play", daemon=True).start()

    # ---- set-up -------------------------------------------------------------------------------------------------
    @staticmethod
    def _extent(run: RunContent) -> tuple[np.ndarray, np.ndarray]:
        if run.scene.volume is not None:
            return np.asarray(run.scene.volume.min, float), np.asarray(run.scene.volume.max, float)
        state = run.state(run.frames[0])
        pos = np.vstack([state.visual_positions, state.physical_positions, np.zeros((1, 3))])
        return pos.min(0).astype(float), pos.max(0).astype(float) + 1e-3

    def _top_speed(self) -> float:
        """The 99th percentile of the first frame's particle speeds (the red end of the colour scale)."""
        state = self.runs[0].state(self.runs[0].frames[0])
        if state.num_physical == 0:
            return 1.0
        return max(float(np.percentile(np.linalg.norm(state.physical_velocities, axis=1), 99)), 1e-3)

    def _build_gui(self, fps: float) -> None:
        gui = self.server.gui
        names = " | ".join(f"**{'AB'[i]}** {r.name} ({r.run.info.get('kind', 'run')}, frames "
                           f"{r.frames[0]}-{r.frames[-1]})" for i, r in enumerate(self.runs))
        gui.add_markdown(names)
        self.frame = gui.add_slider("frame", min=self.times[0], max=max(self.times[-1], self.times[0] + 1), step=1,
                                    initial_value=self.times[0], disabled=len(self.times) < 2)
        self.play = gui.add_checkbox("play", initial_value=False)
        self.fps = gui.add_number("play fps", initial_value=float(min(fps, 30.0)), min=1.0, max=60.0, step=1.0)
        self.status = gui.add_markdown("")
        self.smoke_on = gui.add_checkbox("smoke (visual Gaussians)", initial_value=True)
        self.particles_on = gui.add_checkbox("physical particles (speed)", initial_value=False)
        self.speed_top = gui.add_number("red at speed (m/s)", initial_value=round(self.top_speed, 3), min=1e-3,
                                        step=0.05)
        self.cameras_on = gui.add_checkbox("cameras (green input, orange synthesised, red held-out)",
                                           initial_value=True)
        self.scenery_on = gui.add_checkbox("source, obstacles, volume box", initial_value=True)
        self.static_on = gui.add_checkbox("static layer", initial_value=True,
                                          disabled=not any(r.static_layer_file() for r in self.runs))
        views = [m.name for m in self.marks[0]]
        self.look = gui.add_dropdown("look through", options=["(free)"] + views, initial_value="(free)")
        self.layout = gui.add_dropdown("two runs", options=list(LAYOUTS), initial_value=LAYOUTS[0],
                                       disabled=len(self.runs) < 2)
        self.switch = gui.add_button("switch run (toggle)", disabled=len(self.runs) < 2)
        self.which = 0
        self.frame.on_update(lambda _: self.show(int(self.frame.value)))
        self.smoke_on.on_update(lambda _: self._show_smoke(self.smoke_on.value))
        for box in (self.particles_on, self.speed_top):
            box.on_update(lambda _: self.show(self.shown, force=True))
        self.cameras_on.on_update(lambda _: self._set_visible("frusta", self.cameras_on.value))
        self.scenery_on.on_update(lambda _: self._set_visible("scenery", self.scenery_on.value))
        self.static_on.on_update(lambda _: self._set_visible("static", self.static_on.value))
        self.look.on_update(lambda _: self._look_through(self.look.value))
        self.layout.on_update(lambda _: self._place_runs())
        self.switch.on_click(lambda _: self._switch())
        self.server.on_client_connect(lambda client: self._look_through(self.look.value, client))

    def _add_fixed(self, i: int, run: RunContent) -> None:
        """A run's parts that do not change with time: frusta, source, obstacles, volume box."""
        scene, sc = self.server.scene, f"/run{i}"
        frusta = {}
        for mark in self.marks[i]:
            pose = frustum_pose(mark.camera_at(self.times[0]))
            frusta[mark.name] = scene.add_camera_frustum(
                f"{sc}/frusta/{mark.name}", fov=pose.fov, aspect=pose.aspect, scale=0.12 * self.size,
                thickness=0.004 * self.size, color=ROLE_COLORS[mark.role], wxyz=pose.wxyz, position=pose.position)
            scene.add_label(f"{sc}/frusta/{mark.name}/label", f"{mark.name} ({mark.role})", position=(0.0, 0.0, 0.0))
        self.nodes[i].frusta = frusta
        src = run.source()
        if src is not None:
            vertices, faces = disk_mesh(src.center, src.radius, src.direction)
            scene.add_mesh_simple(f"{sc}/scenery/source", vertices, faces, color=SOURCE_COLOR, opacity=0.6)
            scene.add_label(f"{sc}/scenery/source_label", "source", position=tuple(src.center))
        for k, body in enumerate(run.bodies()):
            self._add_body(f"{sc}/scenery/obstacle{k}", body)
        if run.scene.volume is not None:
            segments = box_segments(run.scene.volume.min, run.scene.volume.max)
            scene.add_line_segments(f"{sc}/scenery/volume", segments, colors=(90, 90, 90),
                                    thickness=0.002 * self.size)

    def _add_body(self, name: str, body: Body) -> None:
        color = BODY_COLORS[body.origin]
        if body.vertices is not None:
            self.server.scene.add_mesh_simple(name, body.vertices.astype(np.float32), body.faces.astype(np.uint32),
                                              color=color, opacity=0.7)
        else:
            self.server.scene.add_icosphere(name, radius=body.radius, color=color, position=body.center,
                                            wireframe=body.origin == "found", opacity=0.7)
        at = body.vertices.mean(0) if body.center is None else np.zeros(3)  # relative to the body's node
        self.server.scene.add_label(f"{name}/label", body.label, position=tuple(at))

    def _load_static_layers(self) -> None:
        """The static layers (RUN/static.npz), read in the background: reading one loads the engine's modules."""
        try:
            for i, run in enumerate(self.runs):
                path = run.static_layer_file()
                if path is None:
                    continue
                from ..scenery.static_layer import load_static

                try:
                    layer = load_static(path)
                except InputError as err:
                    log.warning("viewer: static layer not shown (%s)", err)
                    continue
                splats = gaussian_splats(layer.means, layer.colors, layer.scales, layer.quats, layer.opacities)
                with self._lock:
                    self.static[i] = self.server.scene.add_gaussian_splats(
                        f"/run{i}/static/splats", splats.centers, splats.covariances, splats.rgbs, splats.opacities)
                log.info("viewer: static layer of %s (%d Gaussians)", run.name, len(splats))
        finally:
            self.static_loaded.set()

    # ---- time ---------------------------------------------------------------------------------------------------
    def show(self, t: int | None, force: bool = False) -> None:
        """Draw frame ``t`` of every run (a run without that frame shows no smoke)."""
        if t is None:
            return
        with self._lock:
            if t == self.shown and not force:
                return
            notes = []
            with self.server.atomic():
                for i, run in enumerate(self.runs):
                    notes.append(self._show_run(i, run, t))
                self._update_frusta(t)
            self.shown = t
            self.status.content = f"frame {t} (t = {t / self.runs[0].scene.fps:.2f} s): " + "; ".join(notes)

    def _show_run(self, i: int, run: RunContent, t: int) -> str:
        scene, node = self.server.scene, self.nodes[i]
        state = run.state(t)
        label = "AB"[i] if len(self.runs) > 1 else run.name
        if state is None:
            self._drop(node, "smoke", "particles")
            return f"{label}: no frame {t}"
        splats = state_splats(state)
        if len(splats):
            node.smoke = scene.add_gaussian_splats(f"/run{i}/smoke", splats.centers, splats.covariances,
                                                   splats.rgbs, splats.opacities, visible=self.smoke_on.value)
        else:
            self._drop(node, "smoke")
        if self.particles_on.value and state.num_physical:
            colors = speed_colors(state.physical_velocities, float(self.speed_top.value))
            node.particles = scene.add_point_cloud(f"/run{i}/particles", state.physical_positions, colors,
                                                   point_size=0.006 * self.size, point_shape="circle")
        else:
            self._drop(node, "particles")
        return f"{label}: {state.num_visual} Gaussians, {state.num_physical} particles"

    @staticmethod
    def _drop(node: RunNodes, *parts: str) -> None:
        for part in parts:
            if getattr(node, part) is not None:
                getattr(node, part).remove()
                setattr(node, part, None)

    def _update_frusta(self, t: int) -> None:
        for i, marks in enumerate(self.marks):
            for mark in marks:
                handle = self.nodes[i].frusta[mark.name]
                if mark.poses is not None:
                    pose = frustum_pose(mark.camera_at(t))
                    handle.wxyz, handle.position = pose.wxyz, pose.position
                image = self.thumbnails[i].get(mark.name, t)
                if image is not None:
                    handle.image = image

    def _thumbnail_ready(self, name: str) -> None:
        with self._lock:
            if self.shown is not None:
                self._update_frusta(self.shown)

    def _play_loop(self) -> None:
        while not self._stop.is_set():
            if not (self.play.value and len(self.times) > 1):
                time.sleep(0.05)
                continue
            start = time.perf_counter()
            at = self.times.index(self.shown) if self.shown in self.times else -1
            self.frame.value = self.times[(at + 1) % len(self.times)]  # calls show()
            time.sleep(max(0.0, 1.0 / max(float(self.fps.value), 1e-3) - (time.perf_counter() - start)))

    # ---- layout and visibility ------------------------------------------------------------------------------------
    def _place_runs(self) -> None:
        side = self.layout.value == LAYOUTS[0]
        step = 1.25 * float(self.hi[0] - self.lo[0])
        with self._lock:
            for i, node in enumerate(self.nodes):
                node.offset = np.array([step * i if side else 0.0, 0.0, 0.0])
                node.group.position = tuple(node.offset)
                node.group.visible = side or i == self.which

    def _switch(self) -> None:
        self.which = (self.which + 1) % len(self.runs)
        if self.layout.value != LAYOUTS[0]:
            self._place_runs()

    def _show_smoke(self, visible: bool) -> None:
        """Show or hide the shown frame's smoke in place (its splats are not sent again)."""
        with self._lock:
            for node in self.nodes:
                if node.smoke is not None:
                    node.smoke.visible = visible

    def _set_visible(self, part: str, visible: bool) -> None:
        with self._lock:
            for node in self.nodes:
                node.parts[part].visible = visible

    def _look_through(self, name: str, client=None) -> None:
        """Put the browsers' cameras (or one client's) at a scene camera: its pose and vertical field of view."""
        marks = {m.name: m for m in self.marks[0]}
        with self._lock:  # the camera looked through would cover the view with its own frustum
            for node in self.nodes:
                for view, handle in node.frusta.items():
                    handle.visible = view != name
        if name not in marks:
            return
        pose = frustum_pose(marks[name].camera_at(self.shown or 0))
        for c in [client] if client is not None else list(self.server.get_clients().values()):
            with c.atomic():
                c.camera.wxyz = pose.wxyz
                c.camera.position = pose.position
                c.camera.fov = pose.fov

    def close(self) -> None:
        self._stop.set()


@dataclass(frozen=True)
class Served:
    """A running viewer: ``url`` to open, ``viewer`` and its ``server`` (``stop()`` it)."""

    url: str
    viewer: Viewer
    server: object

    def stop(self) -> None:
        self.viewer.close()
        self.server.stop()


def open_viewer(run_paths: list, host: str = "127.0.0.1", port: int = 8080) -> Served:
    """Open one or two run folders and serve them at ``http://host:port`` (returns once the first frame is set).

    Raises:
        InputError: a folder is not a run, viser is missing, or ``host:port`` cannot be listened on.
    """
    runs = [RunContent.open(p) for p in run_paths]
    check_port(host, port)
    viser = require_viser()
    server = viser.ViserServer(host=host, port=port, verbose=False)
    if server.get_port() != port:  # viser moves on to the next free port; we said which one we would use
        server.stop()
        raise InputError(None, "--port", f"{port} was taken while the viewer started; pick another --port")
    return Served(f"http://{host}:{port}", Viewer(server, runs), server)


def serve(run_paths: list, host: str = "127.0.0.1", port: int = 8080) -> None:
    """Serve the viewer until interrupted (Ctrl-C)."""
    started = time.perf_counter()
    served = open_viewer(run_paths, host, port)
    where = "this machine only; --host 0.0.0.0 shares it on the network" if host in ("127.0.0.1", "localhost",
                                                                                     "::1") else "on the network"
    log.info("viewer at %s (%s): %d frames, first frame ready in %.1f s; Ctrl-C stops it", served.url, where,
             len(served.viewer.times), time.perf_counter() - started)
    try:
        while True:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        served.stop()

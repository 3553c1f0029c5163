"""Firmware in the loop through the dashboard (`--fil serve`): `dollop serve` drives the
emulated board instead of `dollop send`, and the pins are compared with the simulator as
in the print scenario (fil.compare, fil.check_printed).

The harness runs `dollop serve --listen 127.0.0.1:0 --board tcp:127.0.0.1:PORT --config
MACHINE` and then does, over HTTP on loopback only, what the Print page (assets/app.js)
does: it follows /api/boards/events (server-sent events, ten a second: what the page
draws), finds the emulated board there, slices the design on the Design page's endpoints
(/api/configs/0, /api/config/check, /api/slice with the page's multipart form), sends the
job with /api/boards/ID/send, pauses and resumes once mid-print, and follows the status
until the print is finished. The dashboard has no way to take a ready .dlp (the page
slices, then sends by job number), so the job sent is the dashboard's own; its job.dlp is
downloaded, kept in the log dir and compared byte for byte with --job (the simulator runs
on the job actually sent either way).

The emulated chip runs only while the harness's main thread is inside Board.run (QEMU
halts at every debugger stop and between runs), so the page's part runs in a thread of its
own (Driver) and the main thread keeps the board running until the driver is done. The
driver never touches the emulator (the gdb link is the main thread's); it only reads the
pin log's list lengths, which the main thread appends to.
"""

import json
import os
import signal
import subprocess
import threading
import time
import urllib.error
import urllib.request
import uuid

import emulate as E
from emulator import fil as F


class Dashboard:
    """One `dollop serve` process against the emulated board's UART, with its stdout and
    stderr in the log dir, and the HTTP calls the page makes. Registered in fil.HOSTS, so
    it is killed on every exit path of the run."""

    def __init__(self, args, board, log_dir):
        self.out_path = os.path.join(log_dir, "serve-%s.stdout.log" % board.label)
        self.err_path = os.path.join(log_dir, "serve-%s.stderr.log" % board.label)
        self.out = open(self.out_path, "w")
        self.err = open(self.err_path, "w")
        # Port 0: the server binds a free port and prints it (no race with another run).
        # --sim-speed 0.1: the simulated board the dashboard always lists runs its control
        # loop in the server process; slowed down it takes less CPU from QEMU.
        self.cmd = [args.dollop, "serve", "--listen", "127.0.0.1:0", "--board", "tcp:127.0.0.1:%d" % board.port,
                    "--config", args.config, "--no-usb", "--sim-speed", "0.1"]
        self.p = subprocess.Popen(self.cmd, stdout=self.out, stderr=self.err, stdin=subprocess.DEVNULL,
                                  preexec_fn=E.die_with_parent)
        F.HOSTS.append(self)
        self.base = None
        # No proxy: an http_proxy in the environment must not see loopback requests.
        self.opener = urllib.request.build_opener(urllib.request.ProxyHandler({}))
        self.tab = "fil-%s" % uuid.uuid4().hex[:12]

    def address(self, wall):
        """Waits for "dollop dashboard: http://127.0.0.1:PORT/" on its stdout."""
        deadline = time.monotonic() + wall
        while time.monotonic() < deadline:
            if self.p.poll() is not None:
                raise F.FilError("dollop serve exited (%s): %s" % (self.p.returncode, self.stderr_tail()))
            self.out.flush()
            with open(self.out_path) as f:
                for line in f:
                    if line.startswith("dollop dashboard: http://"):
                        self.base = line.split(": ", 1)[1].strip().rstrip("/")
                        if not self.base.startswith("http://127.0.0.1:"):
                            raise F.FilError("dollop serve listens on %s, not loopback" % self.base)
                        return self.base
            time.sleep(0.05)
        raise F.FilError("dollop serve printed no address in %.0f s: %s" % (wall, self.stderr_tail()))

    def stderr_tail(self, n=600):
        try:
            if not self.err.closed:
                self.err.flush()
            with open(self.err_path, errors="replace") as f:
                text = f.read().strip()
        except (OSError, ValueError):
            return "(no stderr)"
        return ("..." + text[-n:] if len(text) > n else text) or "(stderr empty)"

    # ---- HTTP, as the page calls it ------------------------------------------------
    def request(self, path, body=None, ctype=None, timeout=60.0):
        req = urllib.request.Request(self.base + path, data=body, method="POST" if body is not None else "GET")
        if ctype:
            req.add_header("Content-Type", ctype)
        try:
            with self.opener.open(req, timeout=timeout) as r:
                data = r.read()
                kind = r.headers.get("Content-Type", "")
        except urllib.error.HTTPError as e:
            text = e.read().decode(errors="replace")
            try:
                text = json.loads(text).get("error", text)
            except ValueError:
                pass
            raise DashboardRefused("%s %s: HTTP %d: %s" % ("POST" if body is not None else "GET", path, e.code, text))
        return json.loads(data) if "json" in kind else data

    def get(self, path):
        return self.request(path)

    def post_json(self, path, obj, timeout=60.0):
        return self.request(path, json.dumps(obj).encode(), "application/json", timeout)

    def post_form(self, path, fields):
        """multipart/form-data, as the page's FormData: (name, value) or (name, filename, bytes)."""
        boundary = "dollopfil%s" % uuid.uuid4().hex
        parts = []
        for f in fields:
            if len(f) == 3:
                head = 'Content-Disposition: form-data; name="%s"; filename="%s"\r\nContent-Type: ' \
                       'application/octet-stream\r\n\r\n' % (f[0], f[1])
                data = f[2]
            else:
                head = 'Content-Disposition: form-data; name="%s"\r\n\r\n' % f[0]
                data = f[1].encode()
            parts.append(b"--" + boundary.encode() + b"\r\n" + head.encode() + data + b"\r\n")
        body = b"".join(parts) + b"--" + boundary.encode() + b"--\r\n"
        return self.request(path, body, "multipart/form-data; boundary=%s" % boundary, timeout=300)

    def action(self, board_id, action, timeout=60.0, **extra):
        """A Print-page button: POST /api/boards/ID/ACTION with this tab's id."""
        return self.post_json("/api/boards/%d/%s" % (board_id, action), dict(tab=self.tab, force=False, **extra),
                              timeout)["message"]

    def kill(self, sig=None):
        """Ctrl-C first (it says "stopping" and exits), SIGKILL if it lingers."""
        if self.p.poll() is None:
            self.p.send_signal(sig or signal.SIGINT)
            try:
                self.p.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.p.kill()
        self.p.wait()
        for f in (self.out, self.err):
            if not f.closed:
                f.close()


class DashboardRefused(Exception):
    """The dashboard answered an API call with an error (its message is the page's)."""


class Follower(threading.Thread):
    """Reads /api/boards/events as the page's EventSource does and keeps every view of the
    emulated board (found by its port), with the wall time it came."""

    def __init__(self, dash, port):
        super().__init__(name="sse", daemon=True)
        self.dash, self.port = dash, "tcp:127.0.0.1:%d" % port
        self.cond = threading.Condition()
        self.views = []  # (wall s, view)
        self.latest = None
        self.events = 0
        self.listed = None  # the first event's boards: (id, name, port, simulated)
        self.error = None
        self.closed = False

    def run(self):
        url = "%s/api/boards/events?tab=%s" % (self.dash.base, self.dash.tab)
        try:
            with self.dash.opener.open(url, timeout=60) as r:
                event, data = None, []
                for raw in r:
                    line = raw.decode(errors="replace").rstrip("\r\n")
                    if line.startswith(":"):
                        continue  # keep-alive comment
                    if line:
                        field, _, value = line.partition(":")
                        value = value[1:] if value.startswith(" ") else value
                        if field == "event":
                            event = value
                        elif field == "data":
                            data.append(value)
                        continue
                    if event == "boards" and data:
                        self.take(json.loads("\n".join(data)))
                    event, data = None, []
        except Exception as e:  # the server killed at the end, or a real failure: kept
            self.error = e
        finally:
            with self.cond:
                self.closed = True
                self.cond.notify_all()

    def take(self, d):
        now = time.monotonic()
        with self.cond:
            self.events += 1
            if self.listed is None:
                self.listed = [(b["id"], b["name"], b["port"], b["simulated"]) for b in d["boards"]]
            mine = [b for b in d["boards"] if b["port"] == self.port]
            if mine:
                self.latest = mine[0]
                self.views.append((now, mine[0]))
            self.cond.notify_all()

    def wait(self, pred, wall, what):
        """The first view (from now on, or the latest) for which pred holds."""
        deadline = time.monotonic() + wall
        with self.cond:
            while True:
                if self.latest is not None and pred(self.latest):
                    return self.latest
                if self.closed:
                    raise F.FilError("the status stream ended while waiting for %s (%s)" % (what, self.error))
                left = deadline - time.monotonic()
                if left <= 0:
                    v = self.latest or {}
                    raise F.FilError("no %s within %.0f s: the board shows %r, %r, message %r" % (
                        what, wall, v.get("activity"), v.get("mode"), v.get("message")))
                self.cond.wait(min(left, 1.0))


class Driver(threading.Thread):
    """What a user does on the pages, in order; the figures in `self.r`, an exception in
    `self.error`. `done` is set at the end either way (the main thread's `until`)."""

    def __init__(self, dash, board, args, log_dir):
        super().__init__(name="page", daemon=True)
        self.dash, self.board, self.args, self.log_dir = dash, board, args, log_dir
        self.done = threading.Event()
        self.r = {}
        self.error = None
        self.fol = None

    def run(self):
        try:
            self.steps()
        except Exception as e:
            self.error = e
        finally:
            self.done.set()

    def steps(self):
        d, a, r, b = self.dash, self.args, self.r, self.board
        d.address(60)
        info = d.get("/api/info")
        r["info_boards"] = info["boards"]
        self.fol = fol = Follower(d, b.port)
        fol.start()
        # The board is listed and the dashboard has said hello to the firmware.
        # A fresh board has no machine config yet: "unconfigured" (mode Unconfigured).
        v = fol.wait(lambda v: v["connected"] and v["mode"] in ("Unconfigured", "Idle"), 120,
                     "board connected and idle")
        r["listed"] = fol.listed
        r["id"] = bid = v["id"]
        r["first"] = dict(activity=v["activity"], mode=v["mode"], homed=v["homed"])
        # The Design page: the --config config (offered first), checked, then sliced.
        cfg = d.get("/api/configs/0")
        text = d.post_json("/api/config/check", {"text": cfg["text"], "edits": []})["text"]
        opts = dict(invert=False, markers=False, calibration_pattern=False)
        opts.update(json.loads(a.slice_options))
        with open(a.design, "rb") as f:
            design = f.read()
        job = d.post_form("/api/slice", [("design", os.path.basename(a.design), design), ("config", text),
                                         ("options", json.dumps(opts))])
        r["job_id"], r["job_name"] = job["id"], job["figures"]["name"]
        dlp = d.get("/api/jobs/%d/job.dlp" % job["id"])
        r["dlp_path"] = os.path.join(self.log_dir, "serve-job.dlp")
        with open(r["dlp_path"], "wb") as f:
            f.write(dlp)
        with open(a.job, "rb") as f:
            r["same_job"] = f.read() == dlp
        r["dlp_len"] = len(dlp)
        # Send: the order returns once the job is uploaded, checked, homed and started.
        t0 = time.monotonic()
        r["send"] = d.action(bid, "send", timeout=900, job=job["id"])
        r["send_wall"] = time.monotonic() - t0
        if a.pause_at > 0:
            self.pause_resume(bid)
        v = fol.wait(lambda v: v["progress"] >= 1.0 and v["activity"].startswith("finished") or
                     v["mode"] == "Halted" or not v["connected"], a.job_wall, "finished print")
        r["end"] = v
        r["print_wall"] = time.monotonic() - t0

    def pause_resume(self, bid):
        """Pause at --pause-at through the dashboard, check the board holds (no STEP edge
        and no valve opened for 2 s of wall time), resume."""
        d, a, r, b, fol = self.dash, self.args, self.r, self.board, self.fol
        fol.wait(lambda v: v["progress"] >= a.pause_at and v["activity"] == "printing" or v["progress"] >= 1.0,
                 a.job_wall, "progress %.0f %%" % (100 * a.pause_at))
        if fol.latest["progress"] >= 1.0:
            r["pause"] = "the print ended before %.0f %%" % (100 * a.pause_at)
            return
        r["pause_asked"] = fol.latest["progress"]
        r["valves_at_pause"] = len(b.log.valves)
        r["pause_msg"] = d.action(bid, "pause")
        r["paused_view"] = fol.wait(lambda v: v["activity"] == "paused", 120, "paused")
        # Held: read from the pin log's lengths (appended by the main thread only).
        edges, writes = len(b.log.edges), len(b.log.writes)
        time.sleep(2.0)
        held = b.log.writes[writes:]
        r["held_edges"] = len(b.log.edges) - edges
        r["held_opens"] = sum(1 for t, k, port, w in held if port == "GPIOA" and w & 0xF)
        r["held_mask"] = b.log.mask
        r["valves_before_resume"] = len(b.log.valves)
        r["resume_msg"] = d.action(bid, "resume")
        fol.wait(lambda v: v["activity"] == "printing" or v["progress"] >= 1.0, 120, "printing again")
        r["pause"] = "ok"


def scenario_serve(image, args, log_dir, machine, boards, rows):
    """Returns (checks, compare's summary or None)."""
    b = F.new_board(image, args, log_dir, "serve", machine, boards)
    dash = Dashboard(args, b, log_dir)
    drv = Driver(dash, b, args, log_dir)
    w0, v0 = time.monotonic(), b.now()[0]
    try:
        drv.start()
        # The chip runs while the page's thread works; a stop wakes this loop at least
        # every 0.25 s of wall time to look at `done`.
        why = b.run(args.job_wall + 300, until=drv.done.is_set)
        wall, virtual = time.monotonic() - w0, (b.now()[0] - v0) / 1e9
    finally:
        dash.kill()
        if drv.fol is not None:
            drv.fol.join(10)
    drv.join(10)
    r = drv.r
    if drv.fol is not None:
        # What the page was shown, for diagnosis (--keep-log keeps it).
        with open(os.path.join(log_dir, "serve-status.jsonl"), "w") as f:
            for t, v in drv.fol.views:
                f.write(json.dumps(dict(wall=round(t - w0, 3), **v)) + "\n")
    if drv.error is not None or why != "until":
        raise F.FilError("the dashboard did not finish the print (%s; board run: %s); dollop serve's stderr: %s" % (
            drv.error or "still running", why, dash.stderr_tail()))
    # The simulator on the job actually sent (--job's rows when they are the same bytes).
    if not r["same_job"]:
        rows = F.simulate(args, r["dlp_path"], args.config, log_dir, "serve-job")
    # The pause is mid-bead: the simulator replays it at the board's pin times (see
    # fil.replay_pause) and the whole print is compared with one time origin.
    if r.get("pause") == "ok" and r["valves_at_pause"] < len(b.log.valves):
        t_after = b.log.valves[r["valves_at_pause"]][0]
        rows, figs = F.replay_pause(args, log_dir, b, rows, t_after,
                                    job=None if r["same_job"] else r["dlp_path"])
        r["replay"] = F.replay_words(figs[4])
    ok, lines, summ = F.compare(b, rows)
    res = dict(board=b, ok=ok, lines=lines, summary=summ)
    return checks(r, drv.fol, b, dash, res, wall, virtual), summ


def checks(r, fol, b, dash, res, wall, virtual):
    out = []
    views = [v for _, v in fol.views]
    listed = ", ".join("%d %s (%s)" % (i, n, p) for i, n, p, sim in (r["listed"] or []))
    out.append(("dashboard lists the emulated board", r["info_boards"] == len(r["listed"] or []) and not
                r["first"]["homed"] and r["first"]["mode"] in ("Unconfigured", "Idle"),
                "/api/info: %d boards; status stream: %s; board %d first shown %s, mode %s, %s" % (
                    r["info_boards"], listed, r["id"], r["first"]["activity"], r["first"]["mode"],
                    "homed" if r["first"]["homed"] else "not homed")))
    # Upload, homing and the print as the page saw them.
    acts = []
    for v in views:
        if v["connected"] and (not acts or acts[-1] != v["activity"]):
            acts.append(v["activity"])
    uploads = [v["upload"] for v in views if v["upload"]]
    up_done = bool(uploads) and uploads[-1][0] == uploads[-1][1]
    # While the board homes (inside the send order) the page sees the board's own status:
    # mode Homing, the head moving, the update count going on.
    homing = [v for v in views if v["activity"] == "homing"]
    homing_live = (any(v["mode"] == "Homing" for v in homing) and len({v["seq"] for v in homing}) > 2
                   and len({tuple(v["position"]) for v in homing}) > 2)
    end = r["end"]
    finished = end["progress"] >= 1.0 and end["activity"].startswith("finished") and end["run"] == "Done" and \
        end["eta_s"] == 0.0 and "uploaded and started" in r["send"]
    out.append(("job sliced, sent, homed and printed from the dashboard", finished and up_done and homing_live,
                "job %d %r: %d B .dlp, %s; send (upload %s B in %d updates, homing shown live in %d updates with "
                "%d positions, start) answered in %.1f s: %r; "
                "activities %s; ended %s at %.0f %% (%s, %s) after %.1f s; %.1f s virtual in %.1f s wall, "
                "%d stops, %d STEP edges" % (
                    r["job_id"], r["job_name"], r["dlp_len"],
                    "byte-identical to --job" if r["same_job"] else "DIFFERENT from --job (simulated on its own)",
                    "%d/%d" % tuple(uploads[-1]) if uploads else "NEVER SHOWN", len(uploads),
                    len({v["seq"] for v in homing}), len({tuple(v["position"]) for v in homing}), r["send_wall"],
                    r["send"],
                    " > ".join(acts), end["activity"], 100 * end["progress"], end["mode"], end["run"],
                    r["print_wall"], virtual, wall, b.stops, len(b.log.edges))))
    # The live status moved: updates kept coming, the head moved, progress only rose.
    printing = [v for v in views if v["activity"] in ("printing", "paused") or v["activity"].startswith("finished")]
    seqs = [v["seq"] for v in views]
    positions = {tuple(v["position"]) for v in printing}
    progress = [v["progress"] for v in printing]
    rising = all(q >= p for p, q in zip(progress, progress[1:]))
    steps = sorted(set(progress))
    live = (len(printing) >= 20 and all(q >= p for p, q in zip(seqs, seqs[1:])) and len(positions) >= 10 and rising
            and len(steps) >= 5)
    out.append(("live status moves (positions, progress)", live,
                "%d status events (%d of the board while printing, seq %d..%d); %d distinct head positions; progress "
                "%d distinct values, %s" % (
                    fol.events, len(printing), seqs[0] if seqs else 0, seqs[-1] if seqs else 0, len(positions),
                    len(steps), "never falling" if rising else "FELL")))
    if "pause" in r:
        ok = r["pause"] == "ok" and r["held_edges"] == 0 and r["held_opens"] == 0 and r["held_mask"] == 0
        fig = r["pause"] if r["pause"] != "ok" else (
            "pause asked at %.1f %% (%r), shown paused at %.1f %% (command %d); held 2 s wall: %d STEP "
            "edges, %d valve-open writes; resume: %r; %s; the pins are compared from the first change after it" % (
                100 * r["pause_asked"], r["pause_msg"], 100 * r["paused_view"]["progress"],
                r["paused_view"]["command"], r["held_edges"],
                r["held_opens"], r["resume_msg"], r.get("replay", "the pause was not replayed")))
        out.append(("pause then resume from the dashboard", ok, fig))
    said = " ".join("%s %s" % (v.get("message") or "", v.get("fault") or "") for v in views)
    out += F.check_printed(res, said + " " + dash.stderr_tail(4000))
    return out

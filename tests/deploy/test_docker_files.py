"""The Docker image and the compose stack, checked without a Docker engine.

Static checks read the Dockerfile (a line parser with ``\\`` continuations), docker-compose.yml
(PyYAML) and .dockerignore. The build context is assembled on this machine, with no network:
the files the Dockerfile COPYs go into a build directory (minus what .dockerignore drops),
which must hold everything ``pip install`` packs from it (pyproject.toml, its readme, every
module of the packages pyproject.toml includes, every package-data file).

The unit suite stops there. With ``KINOPLAN_DEPLOY_TESTS=1`` the image is also emulated: its
``pip install`` lines run in that directory in a fresh virtualenv and install from the
package index as a real build does (network, minutes), and its entry point starts (loopback,
free ports, a temp data dir) until GET /health answers and the HEALTHCHECK command itself
exits 0. Last, the compose stack runs from the same virtualenv: the scheduler and a worker
with the services' own commands (ports moved to free ones) and the API with the api
service's environment; a job must run on the worker, which proves the workers import the
installed packages, and the viewer must ask for the key the api service is given.
"""

from __future__ import annotations

import contextlib
import fnmatch
import http.client as http_client
import json
import os
import re
import shlex
import shutil
import signal
import socket
import subprocess
import sys
import time
import tomllib
import urllib.error
import urllib.request
from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
DOCKERFILE = ROOT / "Dockerfile"
COMPOSE = ROOT / "docker-compose.yml"
DOCKERIGNORE = ROOT / ".dockerignore"

#: What the image needs from the tree, and nothing else.
IMAGE_SOURCES = {"pyproject.toml", "README.md", "app", "kinematics", "kinoplan", "planning",
                 "web"}
#: ENV variables of the image that name a path inside the container.
CONTAINER_PATHS = {"NUMBA_CACHE_DIR"}
START_TIMEOUT_S = 60
PIP_TIMEOUT_S = 900
#: The image's install runs only when asked: it downloads the dependencies.
DEPLOY_TESTS = os.environ.get("KINOPLAN_DEPLOY_TESTS") == "1"
needs_index = pytest.mark.skipif(
    not DEPLOY_TESTS, reason="installs from the package index; set KINOPLAN_DEPLOY_TESTS=1")


# ---- Dockerfile --------------------------------------------------------------------------
def parse_dockerfile(text: str) -> list[tuple[str, str]]:
    """``(INSTRUCTION, arguments)`` in order; comments and blank lines dropped, lines ending
    in ``\\`` joined with the next (comment lines inside a continuation are skipped)."""
    out: list[tuple[str, str]] = []
    pending = ""
    for raw in text.splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if line.endswith("\\"):
            pending += line[:-1].strip() + " "
            continue
        word, _, rest = (pending + line).partition(" ")
        out.append((word.upper(), rest.strip()))
        pending = ""
    assert not pending, "the Dockerfile ends inside a continuation"
    return out


def command_argv(args: str) -> list[str]:
    """Exec form (a JSON array) as is; shell form as ``/bin/sh -c``."""
    if args.startswith("["):
        return json.loads(args)
    return ["/bin/sh", "-c", args]


def healthcheck_argv(args: str) -> list[str]:
    match = re.fullmatch(r"((?:--\S+\s+)*)CMD\s+(.+)", args, flags=re.S)
    assert match, f"HEALTHCHECK without CMD: {args!r}"
    return command_argv(match.group(2).strip())


def env_pairs(args: str) -> dict[str, str]:
    return dict(item.split("=", 1) for item in shlex.split(args))


def copy_sources(args: str) -> tuple[list[str], str]:
    words = json.loads(args) if args.startswith("[") else shlex.split(args)
    words = [w for w in words if not w.startswith("--")]
    return words[:-1], words[-1]


@pytest.fixture(scope="module")
def dockerfile() -> list[tuple[str, str]]:
    return parse_dockerfile(DOCKERFILE.read_text())


def entrypoint_argv(instructions) -> list[str]:
    entry = [command_argv(a) for k, a in instructions if k == "ENTRYPOINT"]
    cmd = [command_argv(a) for k, a in instructions if k == "CMD"]
    return (entry[-1] if entry else []) + (cmd[-1] if cmd else [])


def test_dockerfile_parser_joins_continuations():
    parsed = parse_dockerfile("# c\nFROM x\nRUN a \\\n    # inner\n    && b\n\nexpose 1 2\n")
    assert parsed == [("FROM", "x"), ("RUN", "a && b"), ("EXPOSE", "1 2")]


def test_dockerfile_base_user_ports_health_and_entry(dockerfile):
    kinds = [k for k, _ in dockerfile]
    froms = [a for k, a in dockerfile if k == "FROM"]
    assert len(froms) == 1 and re.fullmatch(r"python:3\.11-slim(@sha256:[0-9a-f]{64})?",
                                            froms[0].split()[0]), froms
    users = [(i, a) for i, (k, a) in enumerate(dockerfile) if k == "USER"]
    assert users, "no USER: the service would run as root"
    last_user_at, user = users[-1]
    assert user.split(":")[0] not in {"root", "0"}
    starts = [i for i, k in enumerate(kinds) if k in {"ENTRYPOINT", "CMD"}]
    assert starts and last_user_at < min(starts), "USER must come before ENTRYPOINT/CMD"
    assert all(i < last_user_at for i, k in enumerate(kinds) if k == "RUN"), \
        "nothing may RUN after switching to the unprivileged user (installs need root)"
    exposed = {p for k, a in dockerfile if k == "EXPOSE" for p in a.split()}
    assert {"8000", "8080"} <= exposed
    env = {k: v for kind, a in dockerfile if kind == "ENV" for k, v in env_pairs(a).items()}
    assert env.get("KINOPLAN_DATA_DIR") == "/data"
    volumes = [json.loads(a) if a.startswith("[") else a.split()
               for k, a in dockerfile if k == "VOLUME"]
    assert ["/data"] in volumes
    checks = [a for k, a in dockerfile if k == "HEALTHCHECK"]
    assert len(checks) == 1
    probe = healthcheck_argv(checks[0])
    assert probe[0] == "python" and "/health" in " ".join(probe)
    assert not any(word in {"curl", "wget"} for word in probe), "slim images have no curl"
    assert entrypoint_argv(dockerfile) == ["python", "-m", "kinoplan", "--host", "0.0.0.0"]
    assert any(k == "ENTRYPOINT" for k in kinds), "flags must append to an ENTRYPOINT"
    installs = [a for k, a in dockerfile if k == "RUN" and "pip install" in a]
    assert installs == ['pip install --no-cache-dir ".[dask]"']


def test_dockerfile_builds_every_kernel_into_a_cache_the_service_user_owns(dockerfile):
    """The image runs the one warm-up command after installing, with numba's cache in a
    directory of its own that it then hands to the unprivileged user: numba writes (and so
    reads) a cache only where it may write, and site-packages belongs to root."""
    env = {k: v for kind, a in dockerfile if kind == "ENV" for k, v in env_pairs(a).items()}
    cache = env.get("NUMBA_CACHE_DIR")
    assert cache and cache.startswith("/") and not cache.startswith("/data"), cache
    runs = [(i, a) for i, (k, a) in enumerate(dockerfile) if k == "RUN"]
    install_at = next(i for i, a in runs if "pip install" in a)
    warm = [(i, a) for i, a in runs if "python -m kinoplan warm-up" in a]
    assert len(warm) == 1, "one warm-up step: python -m kinoplan warm-up"
    warm_at, command = warm[0]
    assert warm_at > install_at, "the warm-up runs the installed package"
    assert command.startswith("cd / "), "from the installed package, not the sources"
    user = next(a for k, a in dockerfile if k == "USER").split(":")[0]
    assert re.search(rf'chown -R {user}(:{user})? "?\$NUMBA_CACHE_DIR"?', command), command
    env_at = next(i for i, (k, a) in enumerate(dockerfile)
                  if k == "ENV" and "NUMBA_CACHE_DIR" in env_pairs(a))
    assert env_at < warm_at, "NUMBA_CACHE_DIR must be set before the warm-up"


def test_dockerfile_copies_only_the_package_sources(dockerfile):
    copied = set()
    for kind, args in dockerfile:
        assert kind != "ADD", "use COPY"
        if kind == "COPY":
            sources, _ = copy_sources(args)
            copied |= {s.rstrip("/") for s in sources}
    assert copied == IMAGE_SOURCES


# ---- .dockerignore ---------------------------------------------------------------------
def ignore_patterns() -> list[str]:
    lines = [ln.strip() for ln in DOCKERIGNORE.read_text().splitlines()]
    patterns = [ln.lstrip("/") for ln in lines if ln and not ln.startswith("#")]
    assert not any(p.startswith("!") for p in patterns), "exceptions are not emulated here"
    return patterns


def ignored(rel: str, patterns: list[str]) -> bool:
    """Docker's rule for a path relative to the context: it, or a folder above it, matches a
    pattern (``**/`` matches any number of folders)."""
    parts = rel.split("/")
    prefixes = ["/".join(parts[: i + 1]) for i in range(len(parts))]
    for pattern in patterns:
        for prefix in prefixes:
            if fnmatch.fnmatchcase(prefix, pattern):
                return True
            if pattern.startswith("**/"):
                tails = ["/".join(prefix.split("/")[j:]) for j in range(prefix.count("/") + 1)]
                if any(fnmatch.fnmatchcase(t, pattern[3:]) for t in tails):
                    return True
    return False


def test_dockerignore_drops_local_state_and_keeps_sources():
    patterns = ignore_patterns()
    for rel in (".venv", ".venv/bin/python", "data", "data/kinoplan.sqlite3", ".git/HEAD",
                "tests/app/test_fuzz_api.py", "app/__pycache__/main.cpython-311.pyc",
                "kinematics/ik/__pycache__", ".pytest_cache", "kinoplan.egg-info"):
        assert ignored(rel, patterns), rel
    for rel in ("pyproject.toml", "README.md", "app/main.py", "app/jobs/kinds.py",
                "kinoplan/__main__.py",
                "kinematics/robots/pile_driver.json", "planning/__init__.py", "web/viewer.py"):
        assert not ignored(rel, patterns), rel


# ---- docker-compose.yml ----------------------------------------------------------------
@pytest.fixture(scope="module")
def compose() -> dict:
    return yaml.safe_load(COMPOSE.read_text())


def service_argv(service: dict, image_argv: list[str]) -> list[str]:
    """What a service runs: its entrypoint (or the image's) and its command."""
    def as_list(v):
        return shlex.split(v) if isinstance(v, str) else list(v)

    if "entrypoint" in service:
        return as_list(service["entrypoint"]) + as_list(service.get("command", []))
    return image_argv + as_list(service.get("command", []))


def environment(service: dict) -> dict:
    env = service.get("environment", {})
    if isinstance(env, list):
        env = dict(item.split("=", 1) if "=" in item else (item, None) for item in env)
    return env


def container_ports(service: dict) -> set[str]:
    return {str(p).rsplit(":", 1)[-1].split("/")[0] for p in service.get("ports", [])}


def published(service: dict) -> list[tuple[str, str, str]]:
    """``(host address, host port, container port)`` of each short-syntax port entry; the
    address is "" when the entry names none (every interface)."""
    out = []
    for entry in service.get("ports", []):
        parts = str(entry).split("/")[0].split(":")
        assert len(parts) in (2, 3), f"unexpected port entry {entry!r}"
        address = parts[0] if len(parts) == 3 else ""
        out.append((address, parts[-2], parts[-1]))
    return out


def test_compose_services(compose, dockerfile):
    services = compose["services"]
    assert set(services) == {"api", "scheduler", "worker"}
    for name, service in services.items():
        build = service.get("build")
        context = build if isinstance(build, str) else (build or {}).get("context")
        assert context in {".", "./"}, f"{name} must run the image built from the Dockerfile"
        assert "container_name" not in service, name
    assert len({s.get("image") for s in services.values()}) == 1, "one image for all"
    assert "kinoplan-data" in (compose.get("volumes") or {})

    api, scheduler, worker = services["api"], services["scheduler"], services["worker"]
    image_argv = entrypoint_argv(dockerfile)
    assert service_argv(api, image_argv) == image_argv
    assert {"8000", "8080"} <= container_ports(api)
    assert ("127.0.0.1", "8000", "8000") in published(api)
    assert ("127.0.0.1", "8080", "8080") in published(api)
    assert environment(api)["KINOPLAN_JOBS_BACKEND"] == "dask://scheduler:8786"
    # The key and the viewer's allowed origins come from the shell or .env, empty by default.
    assert environment(api)["KINOPLAN_API_KEY"] == "${KINOPLAN_API_KEY:-}"
    assert environment(api)["KINOPLAN_ALLOWED_ORIGINS"] == "${KINOPLAN_ALLOWED_ORIGINS:-}"
    assert "kinoplan-data:/data" in api["volumes"]
    assert "scheduler" in api["depends_on"]
    assert api["healthcheck"]["test"][1:] == healthcheck_argv(
        next(a for k, a in dockerfile if k == "HEALTHCHECK")), "api: the image's health check"

    assert service_argv(scheduler, image_argv)[:4] == ["dask", "scheduler", "--port", "8786"]
    assert "8786" in container_ports(scheduler)
    assert "test" in scheduler["healthcheck"]

    argv = service_argv(worker, image_argv)
    # kinoplan's worker command: `dask worker` started again after a lost scheduler.
    assert argv[:4] == ["python", "-m", "app.worker", "tcp://scheduler:8786"]
    assert " ".join(argv[4:]).startswith("--nworkers 1 --nthreads 1")
    assert "ports" not in worker, "a scaled worker cannot publish fixed host ports"
    assert "scheduler" in worker["depends_on"]
    assert "volumes" not in worker and "volumes" not in scheduler


def test_compose_file_is_read_by_compose_v2_and_docker_compose_1_29(compose):
    """Top-level keys both read: services, volumes, networks and extension fields (x-);
    docker-compose 1.29 refuses `name` (a Compose v2 addition)."""
    assert set(compose) - {"services", "volumes", "networks", "configs", "secrets"} <= {
        key for key in compose if key.startswith("x-")}
    assert "name" not in compose and "version" not in compose


def test_compose_publishes_nothing_beyond_this_machine(compose):
    """The API's writes and the viewer are open without a key: no service publishes a port
    on every interface, or on an address taken from the environment."""
    for name, service in compose["services"].items():
        for address, host_port, target in published(service):
            assert address == "127.0.0.1", f"{name} publishes {host_port}:{target} on " \
                f"{address or 'every interface'}"
        assert "${" not in str(service.get("ports", [])), name


# ---- the image, emulated -----------------------------------------------------------------
def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def clean_env(venv: Path, extra: dict[str, str] | None = None) -> dict[str, str]:
    """This shell's environment without project settings or import paths, the venv first on
    PATH, plus ``extra`` (the image's ENV, a service's environment)."""
    env = {k: v for k, v in os.environ.items()
           if not k.startswith("KINOPLAN_") and k not in {"PYTHONPATH", "VIRTUAL_ENV",
                                                           "PYTHONHOME"}}
    env["PATH"] = f"{venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
    env["VIRTUAL_ENV"] = str(venv)
    env.update(extra or {})
    return env


def resolve(argv: list[str], env: dict[str, str]) -> list[str]:
    exe = shutil.which(argv[0], path=env["PATH"])
    assert exe, f"{argv[0]} not found"
    return [exe, *argv[1:]]


@contextlib.contextmanager
def started(argv, *, cwd: Path, env: dict[str, str], log: Path):
    """Run ``argv`` in its own process group; stop that group (TERM, then KILL) on exit."""
    with open(log, "wb") as out:
        proc = subprocess.Popen(resolve(argv, env), cwd=cwd, env=env, stdout=out,
                                stderr=subprocess.STDOUT, start_new_session=True)
    try:
        yield proc
    finally:
        for sig, wait_s in ((signal.SIGTERM, 20), (signal.SIGKILL, 5)):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, sig)
            try:
                proc.wait(wait_s)
                break
            except subprocess.TimeoutExpired:
                continue


def run_probe(argv, env) -> int:
    return subprocess.run(resolve(argv, env), env=env, capture_output=True, timeout=30).returncode


def wait_until(ok, proc, log: Path, what: str, timeout_s: float = START_TIMEOUT_S) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"{what} exited ({proc.returncode}):\n{log.read_text()[-4000:]}")
        if ok():
            return
        time.sleep(0.5)
    pytest.fail(f"{what} not up within {timeout_s} s:\n{log.read_text()[-4000:]}")


def http(method: str, url: str, body=None, headers=None):
    data = None if body is None else json.dumps(body).encode()
    req = urllib.request.Request(url, data=data, method=method,
                                 headers={"content-type": "application/json", **(headers or {})})
    try:
        with urllib.request.urlopen(req, timeout=5) as resp:
            return resp.status, json.loads(resp.read() or b"null")
    except urllib.error.HTTPError as err:
        return err.code, json.loads(err.read() or b"null")


def healthy(port: int) -> bool:
    try:
        return http("GET", f"http://127.0.0.1:{port}/health")[0] == 200
    except OSError:
        return False


class Image:
    """The emulated image: container paths live under ``fs``; ``python`` is ``venv``'s."""

    def __init__(self, root: Path, instructions) -> None:
        self.fs, self.venv, self.instructions = root / "fs", root / "venv", instructions
        self.env: dict[str, str] = {}
        self.workdir = self.fs

    def path(self, container_path: str) -> Path:
        base = self.workdir if not container_path.startswith("/") else self.fs
        return base / container_path.lstrip("/")

    def set_env(self, args: str) -> None:
        """An ENV line; numba's cache directory, a container path, moves under ``fs`` so
        the emulation never writes outside its temp folder."""
        for key, value in env_pairs(args).items():
            self.env[key] = str(self.path(value)) if key in CONTAINER_PATHS else value

    def copy(self, args: str) -> None:
        sources, dest = copy_sources(args)
        target = self.path(dest)
        patterns = ignore_patterns()
        for src in sources:
            src_path = ROOT / src.rstrip("/")
            if src_path.is_dir():   # Docker copies a folder's contents
                def skip(folder, names, src_path=src_path):
                    rel = Path(folder).relative_to(ROOT)
                    return [n for n in names if ignored((rel / n).as_posix(), patterns)]

                shutil.copytree(src_path, target, ignore=skip, dirs_exist_ok=True)
            else:
                dst = target / src_path.name if dest.endswith("/") else target
                dst.parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(src_path, dst)

    def assemble(self) -> Path:
        """The Dockerfile's WORKDIR, ENV and COPY steps up to its first ``pip install``; the
        directory that install runs in (no network needed)."""
        for kind, args in self.instructions:
            if kind == "WORKDIR":
                self.workdir = self.path(args)
                self.workdir.mkdir(parents=True, exist_ok=True)
            elif kind == "ENV":
                self.set_env(args)
            elif kind == "COPY":
                self.copy(args)
            elif kind == "RUN" and "pip install" in args:
                return self.workdir
        raise AssertionError("the Dockerfile installs nothing")

    def build(self) -> None:
        subprocess.run([sys.executable, "-m", "venv", str(self.venv)], check=True, timeout=120)
        for kind, args in self.instructions:
            if kind == "WORKDIR":
                self.workdir = self.path(args)
                self.workdir.mkdir(parents=True, exist_ok=True)
            elif kind == "ENV":
                self.set_env(args)
            elif kind == "COPY":
                self.copy(args)
            elif kind == "RUN" and "pip install" in args:
                # Users, /data and its owner need root and are no business of this machine.
                env = clean_env(self.venv, self.env)
                done = subprocess.run(command_argv(args), cwd=self.workdir, env=env,
                                      capture_output=True, text=True, timeout=PIP_TIMEOUT_S)
                assert done.returncode == 0, f"{args}\n{done.stdout[-3000:]}{done.stderr[-3000:]}"


def package_dirs(root: Path, include: list[str]) -> list[str]:
    """Top-level packages (folders with an ``__init__.py``, as setuptools finds them) of
    ``root`` that pyproject's ``packages.find`` ``include`` patterns pick (``app*`` picks
    ``app`` and everything below it; ``kinoplan*`` not the ``kinoplan.egg-info`` folder)."""
    return sorted(d.name for d in root.iterdir()
                  if (d / "__init__.py").is_file()
                  and any(fnmatch.fnmatchcase(d.name, p) for p in include))


def test_build_context_holds_what_the_install_packs(dockerfile, tmp_path):
    """No network: the directory the Dockerfile's ``pip install`` runs in holds
    pyproject.toml and its readme, every module of the packages pyproject.toml includes and
    every package-data file, as in the source tree (what .dockerignore drops aside)."""
    context = Image(tmp_path, dockerfile).assemble()
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert (context / "pyproject.toml").read_text() == (ROOT / "pyproject.toml").read_text()
    assert (context / project["project"]["readme"]).is_file()
    setuptools_cfg = project["tool"]["setuptools"]
    include = setuptools_cfg["packages"]["find"]["include"]
    packages = package_dirs(ROOT, include)
    assert {"app", "kinematics", "kinoplan", "planning", "web"} <= set(packages)
    assert package_dirs(context, include) == packages
    patterns = ignore_patterns()
    for package in packages:
        modules = {p.relative_to(ROOT).as_posix() for p in (ROOT / package).rglob("*.py")}
        modules = {m for m in modules if not ignored(m, patterns)}
        copied = {p.relative_to(context).as_posix() for p in (context / package).rglob("*.py")}
        assert copied == modules, package
    for package, globs in setuptools_cfg["package-data"].items():
        for pattern in globs:
            files = sorted((ROOT / package.replace(".", "/")).glob(pattern))
            assert files, f"package-data {package}: {pattern} matches nothing"
            for f in files:
                rel = f.relative_to(ROOT).as_posix()
                assert not ignored(rel, patterns), f"{rel} is package data but .dockerignored"
                assert (context / rel).read_bytes() == f.read_bytes(), rel


@pytest.fixture(scope="module")
def image(tmp_path_factory, dockerfile) -> Image:
    built = Image(tmp_path_factory.mktemp("image"), dockerfile)
    built.build()
    return built


@needs_index
def test_image_installs_starts_and_passes_its_healthcheck(image, dockerfile, tmp_path):
    assert not (image.workdir / "app").exists(), "runs from the installed package"
    site = next((image.venv / "lib").glob("python3*/site-packages"))
    for package in ("app", "app/jobs", "kinematics/robots", "kinoplan", "planning", "web"):
        assert (site / package).is_dir(), f"{package} missing from the installed wheel"
    port, viewer_port = free_port(), free_port()
    env = clean_env(image.venv, {**image.env, "KINOPLAN_PORT": str(port)})
    # As the image starts (viewer included), on loopback, free ports and a temp data dir.
    argv = entrypoint_argv(dockerfile) + ["--host", "127.0.0.1", "--viewer-port",
                                          str(viewer_port), "--data-dir", str(tmp_path / "data")]
    probe = healthcheck_argv(next(a for k, a in dockerfile if k == "HEALTHCHECK"))
    assert run_probe(probe, env) != 0, "the health check passes with nothing listening"
    log = tmp_path / "api.log"
    with started(argv, cwd=image.workdir, env=env, log=log) as proc:
        wait_until(lambda: healthy(port), proc, log, "the API")
        assert run_probe(probe, env) == 0
        status, body = http("GET", f"http://127.0.0.1:{port}/health")
        assert body["status"] == "ok" and body["jobs_backend"] == "local"
        assert http("GET", f"http://127.0.0.1:{port}/robots")[0] == 200
        with urllib.request.urlopen(f"http://127.0.0.1:{viewer_port}/", timeout=5) as page:
            assert page.status == 200, "the 3D viewer does not serve its page"
        shown = http("POST", f"http://127.0.0.1:{port}/viewer/show", {"robot": "pile_driver"})
        assert shown[0] == 200 and shown[1]["shown"]["robot"] == "pile_driver"
    assert (tmp_path / "data").is_dir()


@needs_index
def test_compose_stack_runs_a_job_on_a_worker(image, compose, dockerfile, tmp_path):
    services = compose["services"]
    sched_port, dash_port, worker_dash, api_port, viewer_port = (free_port() for _ in range(5))

    def moved(text: str) -> str:
        # Compose's names and fixed ports, moved to this machine's loopback and free ports.
        return (text.replace("scheduler:8786", f"127.0.0.1:{sched_port}")
                .replace("8786", str(sched_port)).replace("8787", str(dash_port))
                .replace("8788", str(worker_dash)))

    def argv_of(name: str) -> list[str]:
        return [moved(a) for a in service_argv(services[name], entrypoint_argv(dockerfile))]

    def probe_of(name: str) -> list[str]:
        test = services[name]["healthcheck"]["test"]
        assert test[0] == "CMD"
        return [moved(a) for a in test[1:]]

    key = "compose-test-key"
    shell = {"KINOPLAN_API_KEY": key}   # as if exported in the shell running compose
    api_env = {k: re.sub(r"\$\{(\w+):-([^}]*)\}", lambda m: shell.get(m[1], m[2]), moved(v))
               for k, v in environment(services["api"]).items()}
    env = clean_env(image.venv, image.env)
    home = image.workdir
    with contextlib.ExitStack() as stack:
        log = tmp_path / "scheduler.log"
        proc = stack.enter_context(started(argv_of("scheduler"), cwd=home, env=env, log=log))
        wait_until(lambda: run_probe(probe_of("scheduler"), env) == 0, proc, log, "scheduler")
        log = tmp_path / "worker.log"
        proc = stack.enter_context(started(argv_of("worker"), cwd=home, env=env, log=log))
        wait_until(lambda: run_probe(probe_of("worker"), env) == 0, proc, log, "worker")
        # Entered last, so stopped first (as compose stops the api before its dependencies).
        log = tmp_path / "api.log"
        api_run_env = {**env, **api_env, "KINOPLAN_PORT": str(api_port)}
        argv = argv_of("api") + ["--host", "127.0.0.1", "--viewer-port", str(viewer_port),
                                 "--data-dir", str(tmp_path / "data")]
        proc = stack.enter_context(started(argv, cwd=home, env=api_run_env, log=log))
        wait_until(lambda: healthy(api_port), proc, log, "the API")
        assert run_probe(probe_of("api"), api_run_env) == 0
        base = f"http://127.0.0.1:{api_port}"
        assert http("GET", f"{base}/health")[1]["jobs_backend"] == f"dask://127.0.0.1:{sched_port}"

        job = {"kind": "echo", "params": {"value": [1, "two", {"three": 3}]}}
        assert http("POST", f"{base}/jobs", job)[0] == 401, "KINOPLAN_API_KEY not passed on"
        status, record = http("POST", f"{base}/jobs", job, {"Authorization": f"Bearer {key}"})
        assert status == 202, record
        deadline = time.monotonic() + START_TIMEOUT_S
        while record["status"] in {"queued", "running"} and time.monotonic() < deadline:
            time.sleep(0.3)
            record = http("GET", f"{base}/jobs/{record['id']}")[1]
        assert record["status"] == "succeeded", (record, (tmp_path / "worker.log").read_text())
        assert http("GET", f"{base}/jobs/{record['id']}/result") == (200, job["params"])

        # The key opens the viewer too: 401 without it, a cookie and a redirect with it.
        viewer = http_client.HTTPConnection("127.0.0.1", viewer_port, timeout=5)
        viewer.request("GET", "/")
        assert viewer.getresponse().status == 401, "the viewer is open despite the key"
        viewer.close()
        viewer = http_client.HTTPConnection("127.0.0.1", viewer_port, timeout=5)
        viewer.request("GET", f"/?key={key}")
        answer = viewer.getresponse()
        assert answer.status == 303 and "HttpOnly" in answer.headers["Set-Cookie"]
        viewer.close()

"""The deployment files have the structure the service relies on. The stack itself is built and run with podman by
tests/integration/test_containers.py (under CI=true); these checks need no container runtime."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from worker.celery_app import BACKEND_QUEUES, GRADE_QUEUE

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def compose() -> dict:
    return yaml.safe_load((ROOT / "docker-compose.yml").read_text())


def queues(service: dict) -> set[str]:
    command = service["command"]
    return set(command[command.index("-Q") + 1].split(","))


def test_every_service_is_there_with_a_healthcheck(compose):
    services = compose["services"]
    assert {"api", "worker-cpu", "worker-rocm", "redis", "postgres"} <= set(services)
    for name, service in services.items():
        if name != "reconciler":
            assert "healthcheck" in service, name
        if "build" in service:
            assert (ROOT / service["build"]["dockerfile"]).is_file(), name


def test_workers_listen_on_their_backend_queue_only(compose):
    services = compose["services"]
    assert queues(services["worker-cpu"]) == {"cpu", GRADE_QUEUE}
    assert queues(services["worker-rocm"]) == {"rocm"}
    assert {"cpu", "rocm"} <= set(BACKEND_QUEUES)
    for name in ("worker-cpu", "worker-rocm"):
        command = services[name]["command"]
        assert command[command.index("-c") + 1] == "1", "one warm Genesis process per worker container"


def test_the_cpu_worker_is_scalable(compose):
    worker = compose["services"]["worker-cpu"]
    assert "container_name" not in worker and "ports" not in worker


def test_the_rocm_worker_gets_the_gpu_devices_and_a_rocm_torch_image(compose):
    rocm = compose["services"]["worker-rocm"]
    assert set(rocm["devices"]) == {"/dev/kfd", "/dev/dri"}
    assert {"video", "render"} <= set(rocm["group_add"])
    dockerfile = (ROOT / rocm["build"]["dockerfile"]).read_text()
    base = next(line for line in dockerfile.splitlines() if line.startswith("FROM "))
    assert "rocm" in base and "torch.version.hip" in dockerfile


def mounted(service: dict) -> set[str]:
    """The sources (named volumes and host paths) a service mounts, in either of compose's volume syntaxes."""
    return {v["source"] if isinstance(v, dict) else v.split(":")[0] for v in service.get("volumes", [])}


def test_the_kernel_cache_is_a_named_volume_of_each_worker(compose):
    assert "genesis-cache" in compose["volumes"]
    for name in ("worker-cpu", "worker-rocm"):
        assert "genesis-cache" in mounted(compose["services"][name])


def test_the_api_and_the_workers_share_no_volume(compose):
    """Issue 24: a worker on another host needs only DATABASE_URL and BROKER_URL. Each worker's ARTIFACTS_DIR is a
    cache in its own container (tests/integration/test_two_hosts.py runs one on a host with a private disk)."""
    services = compose["services"]
    workers = {name: s for name, s in services.items() if name.startswith("worker-")}
    assert set(workers) == {"worker-cpu", "worker-rocm"}
    for side in ("api", "reconciler"):
        for name, worker in workers.items():
            shared = mounted(services[side]) & mounted(worker)
            assert not shared, f"{side} and {name} share {shared}"
    artifacts = compose["x-service-env"]["ARTIFACTS_DIR"]
    for name in ("api", "reconciler", *workers):  # the grader's own containers: no volume over ARTIFACTS_DIR
        service = services[name]
        targets = {v["target"] if isinstance(v, dict) else v.split(":")[1] for v in service.get("volumes", [])}
        assert not any(artifacts.startswith(t.rstrip("/") + "/") or artifacts == t for t in targets), (name, targets)
    assert "artifacts" not in compose["volumes"]


def test_deployment_uses_postgres_and_redis_not_the_embedded_defaults(compose):
    for name in ("api", "worker-cpu", "worker-rocm"):
        env = compose["services"][name]["environment"]
        assert env["DATABASE_URL"].startswith("postgresql") and env["BROKER_URL"].startswith("redis://")
        assert env["ENVIRONMENT"] == "production"


def test_operators_get_flower_on_the_same_broker_and_loopback_only(compose):
    flower = compose["services"]["flower"]
    assert "--broker=redis://redis:6379/0" in flower["command"]
    assert compose["x-service-env"]["BROKER_URL"] == "redis://redis:6379/0"
    assert all(port.startswith("127.0.0.1:") for port in flower["ports"])


def test_the_api_is_reached_only_through_a_tls_and_buffering_proxy(compose):
    """Slow clients (issue 26): nginx reads headers and whole bodies under its own timeouts before the API sees a
    request, terminates TLS, and hands the API the client's address in a header the client cannot write."""
    from grader.core.settings import Settings

    services = compose["services"]
    api, proxy = services["api"], services["proxy"]
    assert "ports" not in api, "the API is published only through the proxy"
    # Per-client limits count clients, not the proxy: X-Forwarded-For is trusted from the proxy's address only.
    import ipaddress

    subnet = ipaddress.ip_network(compose["networks"]["default"]["ipam"]["config"][0]["subnet"])
    proxy_address = proxy["networks"]["default"]["ipv4_address"]
    assert api["environment"]["FORWARDED_ALLOW_IPS"] == proxy_address and ipaddress.ip_address(proxy_address) in subnet
    # ... by the app alone: uvicorn's own handling (on by default) would trust any process on the container's loopback
    command = (ROOT / "docker" / "api.Dockerfile").read_text().split("\nCMD ")[1]
    assert "uvicorn grader.main:app" in command and "--no-proxy-headers" in command
    assert proxy["image"].startswith("nginx:") and {"443:443", "80:80"} <= set(proxy["ports"])
    assert proxy["depends_on"]["api"]["condition"] == "service_healthy"
    config_mount = next(v for v in proxy["volumes"] if v.endswith(":/etc/nginx/nginx.conf:ro"))
    config = (ROOT / config_mount.split(":")[0]).read_text()
    assert "proxy_pass http://grader_api;" in config and "server api:8000;" in config
    assert "proxy_request_buffering on;" in config and "proxy_request_buffering off" not in config
    assert "listen 443 ssl;" in config and "ssl_certificate " in config
    assert "proxy_set_header X-Forwarded-For $remote_addr;" in config  # replaced, never appended to
    for directive in ("client_header_timeout", "client_body_timeout"):
        seconds = int(config.split(f"{directive} ")[1].split("s;")[0])
        assert seconds <= Settings().body_deadline_s, directive
    limit = config.split("client_max_body_size ")[1].split(";")[0]
    assert int(limit) == Settings().max_body_bytes
    assert any(v.startswith("./docker/tls:") for v in proxy["volumes"])
    assert "*.pem" in (ROOT / ".gitignore").read_text()


def _ci_override() -> dict:
    """docker/compose.ci.yml, its compose merge tags (`!override`, `!reset`) read as plain values."""
    class Loader(yaml.SafeLoader):
        pass

    for tag in ("!override", "!reset"):
        Loader.add_constructor(tag, lambda loader, node: (
            loader.construct_sequence(node) if isinstance(node, yaml.SequenceNode) else
            loader.construct_mapping(node) if isinstance(node, yaml.MappingNode) else loader.construct_scalar(node)))
    return yaml.load((ROOT / "docker" / "compose.ci.yml").read_text(), Loader=Loader)


def test_the_ci_override_replaces_only_what_comes_from_a_registry(compose):
    """Issue 36: the container test runs the real docker-compose.yml; its override swaps the registry images for ones
    built here and leaves flower out, nothing else (the test's own third file moves the proxy to a free port)."""
    override = _ci_override()["services"]
    for name, service in override.items():
        assert name in compose["services"], name
        assert set(service) == ({"profiles"} if name == "flower" else {"image"}), (name, set(service))
        if "image" in service:
            assert service["image"].startswith("localhost/"), name
    assert {"postgres", "redis", "proxy", "api", "worker-cpu", "reconciler"} <= set(override)
    assert override["flower"]["profiles"] and not compose["services"]["flower"].get("profiles")


def test_the_images_run_as_a_user_and_install_locked_requirements_only():
    """Issue 36: no image runs as root or installs a package that requirements/*.lock does not pin with a hash."""
    for name in ("api", "worker-cpu", "worker-rocm"):
        dockerfile = (ROOT / "docker" / f"{name}.Dockerfile").read_text()
        users = [line.split()[1] for line in dockerfile.splitlines() if line.startswith("USER ")]
        assert users and users[-1] not in ("root", "0"), name
        assert "--require-hashes" in dockerfile and "requirements/" in dockerfile, name
        assert "HEALTHCHECK" in dockerfile, name


def test_the_cpu_image_lists_the_warm_up_cases_it_compiles_kernels_for():
    """The worker image compiles the kernels of the cases its warm case process loads, listed by a Python line in its
    Dockerfile; a line that fails (it named a constant since removed) would list none and build an image with no
    kernels. The line runs here and names every installed lesson's warm-up cases."""
    import re
    import subprocess
    import sys

    from worker.warm_process import warm_up_cases

    text = (ROOT / "docker" / "worker-cpu.Dockerfile").read_text()
    line = re.search(r'cases=\$\(python -c "([^"]+)"\)', text)
    assert line and "test -n \"$cases\"" in text, "the Dockerfile lists the cases and fails on an empty list"
    listed = subprocess.run([sys.executable, "-c", line[1]], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert listed.returncode == 0, listed.stderr
    assert listed.stdout.split() == [name for name, _ in warm_up_cases()] and listed.stdout.split(), listed.stdout

#!/usr/bin/env python3
"""Checks the deploy/ files without a cluster:

- deploy/k8s/*.yaml parse (PyYAML), hold exactly the expected objects (coordinator Deployment and
  Service, workers Deployment, Redis Deployment and Service), every Deployment's selector matches
  its pod labels, every Service selects a Deployment's pods and targets a port its container
  declares, every probe names a declared port, the coordinator is ready by a TCP probe on its gRPC
  port, and every "service:port" address in container args names a Service and one of its ports;
- credentials (issue 10): the irfarm-tokens Secret holds placeholder tokens too short to be
  accepted; the coordinator pod reads its client and worker token lists and each worker its token
  from files of that Secret mounted read-only (every key named exists); the Containerfile's default
  command and the systemd units pass token files; nothing listens on a non-loopback address
  without --client-token-file and --worker-token-file;
- deploy/Containerfile is Debian 12 based, copies both entry points and installs runtime packages
  that exist (apt-cache, when it knows the Debian package lists);
- deploy/systemd/*.service pass `systemd-analyze verify` with no warning (ExecStart pointed at the
  build's binaries), when systemd-analyze is installed (else the part is skipped with a message).

Usage: deploy_files_test.py REPO_DIR BUILD_DIR
"""
import glob
import os
import re
import shutil
import subprocess
import sys
import tempfile

import yaml

REPO, BUILD = sys.argv[1], sys.argv[2]
DEPLOY = os.path.join(REPO, "deploy")
failures = []


def check(ok, what):
    print(("ok: " if ok else "FAIL: ") + what)
    if not ok:
        failures.append(what)


def pod_ports(deployment):
    """Declared container ports of a Deployment: name -> number, and the numbers."""
    by_name, numbers = {}, set()
    for c in deployment["spec"]["template"]["spec"]["containers"]:
        for p in c.get("ports", []):
            numbers.add(p["containerPort"])
            if "name" in p:
                by_name[p["name"]] = p["containerPort"]
    return by_name, numbers


def port_exists(port, deployment):
    by_name, numbers = pod_ports(deployment)
    return port in by_name if isinstance(port, str) else port in numbers


# --- Kubernetes manifests ---
docs = []
for path in sorted(glob.glob(os.path.join(DEPLOY, "k8s", "*.yaml"))):
    with open(path) as f:
        for d in yaml.safe_load_all(f):
            if d is None:
                continue
            check(all(k in d for k in ("apiVersion", "kind", "metadata")) and "name" in d["metadata"],
                  "%s: object has apiVersion, kind, metadata.name" % os.path.basename(path))
            docs.append(d)
objects = {(d["kind"], d["metadata"]["name"]): d for d in docs}
expected = {("Deployment", "irfarm-coordinator"), ("Service", "irfarm-coordinator"),
            ("Deployment", "irfarm-worker"), ("Deployment", "irfarm-redis"),
            ("Service", "irfarm-redis"), ("Secret", "irfarm-tokens")}
check(set(objects) == expected, "objects are %s" % sorted(objects))
check(len(objects) == len(docs), "no object defined twice")

deployments = {n: d for (k, n), d in objects.items() if k == "Deployment"}
services = {n: d for (k, n), d in objects.items() if k == "Service"}
for name, d in deployments.items():
    check(d["apiVersion"] == "apps/v1", "%s: apps/v1" % name)
    sel = d["spec"]["selector"]["matchLabels"]
    labels = d["spec"]["template"]["metadata"]["labels"]
    check(bool(sel) and all(labels.get(k) == v for k, v in sel.items()),
          "Deployment %s: selector %s matches pod labels" % (name, sel))
    for c in d["spec"]["template"]["spec"]["containers"]:
        check("image" in c and "resources" in c and "requests" in c["resources"],
              "Deployment %s/%s: image and resource requests" % (name, c["name"]))
        for probe in ("readinessProbe", "livenessProbe"):
            if probe in c:
                port = (c[probe].get("tcpSocket") or c[probe].get("grpc") or {}).get("port")
                check(port is not None and port_exists(port, d),
                      "Deployment %s: %s port %r is declared" % (name, probe, port))

for name, s in services.items():
    sel = s["spec"]["selector"]
    targets = [d for d in deployments.values()
               if all(d["spec"]["template"]["metadata"]["labels"].get(k) == v
                      for k, v in sel.items())]
    check(len(targets) == 1, "Service %s selects exactly one Deployment's pods (%d)" %
          (name, len(targets)))
    for p in s["spec"]["ports"]:
        tp = p.get("targetPort", p["port"])
        check(bool(targets) and port_exists(tp, targets[0]),
              "Service %s: targetPort %r is a declared container port" % (name, tp))

coord = deployments.get("irfarm-coordinator")
if coord:
    c = coord["spec"]["template"]["spec"]["containers"][0]
    by_name, _ = pod_ports(coord)
    probe_port = c.get("readinessProbe", {}).get("tcpSocket", {}).get("port")
    check(by_name.get(probe_port) == 50051 or probe_port == 50051,
          "coordinator readiness: TCP probe on the gRPC port 50051 (%r)" % probe_port)
    check("0.0.0.0:50051" in c.get("args", []), "coordinator listens on 0.0.0.0:50051 in the pod")
    check(c.get("command") == ["irfarm-coordinator"], "coordinator entry point")
worker = deployments.get("irfarm-worker")
if worker:
    check(worker["spec"]["template"]["spec"]["containers"][0].get("command") == ["irfarm-worker"],
          "worker entry point")

# Every "name:port" argument must be a Service and one of its ports.
for name, d in deployments.items():
    for c in d["spec"]["template"]["spec"]["containers"]:
        for a in c.get("args", []):
            m = re.fullmatch(r"([a-z][a-z0-9-]*):(\d+)", str(a))
            if not m:
                continue
            svc = services.get(m.group(1))
            check(svc is not None and int(m.group(2)) in [p["port"] for p in svc["spec"]["ports"]],
                  "Deployment %s: address %s is a Service port" % (name, a))

# --- Metrics (issue 11): annotated pods serve --metrics on the annotated, declared port, and the
# Prometheus config's pod job keeps pods by exactly these annotations ---
for name in ("irfarm-coordinator", "irfarm-worker"):
    d = deployments.get(name)
    if not d:
        continue
    ann = d["spec"]["template"]["metadata"].get("annotations", {})
    c = d["spec"]["template"]["spec"]["containers"][0]
    metrics = str(c.get("args", [])[c["args"].index("--metrics") + 1]) if "--metrics" in c.get("args", []) else ""
    port = ann.get("prometheus.io/port", "")
    check(ann.get("prometheus.io/scrape") == "true" and ann.get("prometheus.io/path") == "/metrics",
          "Deployment %s: prometheus.io scrape and path annotations" % name)
    check(port.isdigit() and metrics.endswith(":" + port) and port_exists(int(port), d),
          "Deployment %s: --metrics %s on the annotated, declared port %s" % (name, metrics, port))
prom_path = os.path.join(DEPLOY, "prometheus", "prometheus.yml")
check(os.path.exists(prom_path), "deploy/prometheus/prometheus.yml exists")
if os.path.exists(prom_path):
    with open(prom_path) as f:
        prom = yaml.safe_load(f)
    jobs = {j["job_name"]: j for j in prom.get("scrape_configs", [])}
    pods = jobs.get("irfarm-pods", {})
    sources = {l for r in pods.get("relabel_configs", []) for l in r.get("source_labels", [])}
    check(pods.get("kubernetes_sd_configs", [{}])[0].get("role") == "pod" and
          {"__meta_kubernetes_pod_annotation_prometheus_io_scrape",
           "__meta_kubernetes_pod_annotation_prometheus_io_port",
           "__meta_kubernetes_pod_annotation_prometheus_io_path"} <= sources,
          "prometheus.yml: pod discovery relabelled by the prometheus.io annotations")
    addr_rule = [r for r in pods.get("relabel_configs", []) if r.get("target_label") == "__address__"]
    ok = bool(addr_rule) and re.fullmatch(addr_rule[0]["regex"], "10.0.0.7:50051;9464") is not None and \
        re.sub(addr_rule[0]["regex"], addr_rule[0]["replacement"].replace("$", "\\"),
               "10.0.0.7:50051;9464") == "10.0.0.7:9464"
    check(ok, "prometheus.yml: __address__ rewritten to the pod IP and the annotated port")

# --- Credentials ---
def flag_value(args, flag):
    args = [str(a) for a in args]
    return args[args.index(flag) + 1] if flag in args and args.index(flag) + 1 < len(args) else None


def listens_safely(args, what):
    """A --listen on a non-loopback address must come with both token files."""
    addr = flag_value(args, "--listen") or "127.0.0.1:50051"
    loopback = addr.startswith("127.") or addr.startswith("localhost") or addr.startswith("[::1]")
    check(loopback or (flag_value(args, "--client-token-file") and
                       flag_value(args, "--worker-token-file")),
          "%s: listens on %s with client and worker token files" % (what, addr))


secret = objects.get(("Secret", "irfarm-tokens"))
if secret:
    data = secret.get("stringData", {})
    check(set(data) == {"client-tokens", "worker-tokens", "worker-token"},
          "Secret irfarm-tokens keys %s" % sorted(data))
    check(all(len(str(v).split()[-1]) < 16 for v in data.values()),
          "Secret irfarm-tokens: placeholders too short to be accepted as tokens")


def secret_file(deployment, path):
    """True when `path` is a key of irfarm-tokens mounted read-only in the deployment's pod."""
    spec = deployment["spec"]["template"]["spec"]
    volumes = {v["name"]: v for v in spec.get("volumes", [])}
    for c in spec["containers"]:
        for m in c.get("volumeMounts", []):
            v = volumes.get(m["name"], {}).get("secret")
            if not v or v.get("secretName") != "irfarm-tokens" or not m.get("readOnly"):
                continue
            prefix = m["mountPath"].rstrip("/") + "/"
            if not path.startswith(prefix):
                continue
            name = path[len(prefix):]
            items = {i["path"]: i["key"] for i in v.get("items", [])} or {k: k for k in
                                                                        (secret or {}).get(
                                                                            "stringData", {})}
            return name in items and items[name] in (secret or {}).get("stringData", {})
    return False


if coord:
    args = coord["spec"]["template"]["spec"]["containers"][0].get("args", [])
    listens_safely(args, "k8s coordinator")
    for flag in ("--client-token-file", "--worker-token-file"):
        path = flag_value(args, flag)
        check(path is not None and secret_file(coord, path),
              "k8s coordinator: %s %s is a mounted key of irfarm-tokens" % (flag, path))
if worker:
    path = flag_value(worker["spec"]["template"]["spec"]["containers"][0].get("args", []),
                      "--token-file")
    check(path is not None and secret_file(worker, path),
          "k8s worker: --token-file %s is a mounted key of irfarm-tokens" % path)

# --- Containerfile ---
with open(os.path.join(DEPLOY, "Containerfile")) as f:
    cf = f.read()
froms = re.findall(r"^FROM\s+(\S+)", cf, re.M)
check(bool(froms) and all(f == "debian:12" for f in froms), "Containerfile: FROM debian:12 (%s)" % froms)
for b in ("irfarm-coordinator", "irfarm-worker"):
    check(re.search(r"^COPY .*/%s\b" % b, cf, re.M) is not None, "Containerfile copies %s" % b)
check(re.search(r"^(CMD|ENTRYPOINT) ", cf, re.M) is not None, "Containerfile has a default command")
cmd = re.search(r"^CMD (\[.*?\])\s*$", cf.replace("\\\n", " "), re.M | re.S)
cmd_args = __import__("json").loads(cmd.group(1)) if cmd else []
listens_safely(cmd_args, "Containerfile CMD")
install = re.search(r"apt-get install[^\n\\]*((?:\\\n[^\n\\]*)*)", cf)
pkgs = [p for p in re.findall(r"[a-z0-9][a-z0-9.+-]+", install.group(1) if install else "")
        if p not in ("rm", "rf", "var", "lib", "apt", "lists", "useradd", "system", "uid", "home",
                     "dir", "create", "irfarm")] if install else []
if shutil.which("apt-cache") and subprocess.run(["apt-cache", "show", "libc6"],
                                                capture_output=True).returncode == 0:
    pkgs = [p for p in pkgs if re.fullmatch(r"lib[a-z0-9.+-]+|ca-certificates|zlib1g", p)]
    missing = []
    if subprocess.run(["apt-cache", "show"] + pkgs, capture_output=True).returncode != 0:
        missing = [p for p in pkgs if subprocess.run(["apt-cache", "show", p],
                                                     capture_output=True).returncode != 0]
    check(len(pkgs) >= 10 and not missing,
          "Containerfile: %d runtime packages known to apt (unknown: %s)" % (len(pkgs), missing))
else:
    print("skip: apt-cache has no package lists; runtime package names not checked")

# --- systemd units ---
units = sorted(glob.glob(os.path.join(DEPLOY, "systemd", "*.service")))
for u in units:
    with open(u) as f:
        text = f.read()
    exec_start = re.search(r"^ExecStart=(.*)$", text, re.M).group(1).split()
    creds = dict(re.findall(r"^LoadCredential=([^:]+):(\S+)$", text, re.M))
    flags = (["--client-token-file", "--worker-token-file"] if "coordinator" in u
             else ["--token-file"])
    for flag in flags:
        path = flag_value(exec_start, flag) or ""
        check(path.startswith("%d/") and path[3:] in creds,
              "%s: %s %s is a LoadCredential" % (os.path.basename(u), flag, path))
check({os.path.basename(u) for u in units} ==
      {"irfarm-coordinator.service", "irfarm-worker@.service"}, "systemd units present")
if shutil.which("systemd-analyze"):
    tmp = tempfile.mkdtemp(prefix="irfarm-units-")
    try:
        names = []
        for u in units:
            with open(u) as f:
                text = f.read().replace("/usr/local/bin/", os.path.abspath(BUILD) + "/")
            base = os.path.basename(u)
            with open(os.path.join(tmp, base), "w") as f:
                f.write(text)
            names.append(os.path.join(tmp, base.replace("@.", "@1.")))  # an instance
        r = subprocess.run(["systemd-analyze", "verify", "--man=no"] + names,
                           capture_output=True, text=True, timeout=60)
        out = (r.stdout + r.stderr).strip()
        check(r.returncode == 0 and not out,
              "systemd-analyze verify %s%s" % (" ".join(map(os.path.basename, names)),
                                                ("\n" + out) if out else ""))
    finally:
        shutil.rmtree(tmp)
else:
    print("skip: systemd-analyze not installed; systemd units not verified")

if failures:
    print("%d check(s) failed" % len(failures))
    sys.exit(1)
print("PASS")

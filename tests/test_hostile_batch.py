"""Hostile input to ``brdffit batch`` / ``fit_many``: names that would escape the output folder,
symbolic links and special files in it, lists of paths that are not text or too large, scheduler
addresses that are not addresses, a read-only output folder, and the local cluster's doors
(TLS with credentials of its own, no HTTP server).

The fits are of one small table (16×16×32 MERL layout, 400 cells after ``subsample``) on one
single-threaded local worker shared by the module, as in ``tests/test_batch.py``.
"""

import os
import socket
import ssl
import stat
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import brdffit
from brdffit.batch import BatchInputError, inputs, outdir, runner

distributed = pytest.importorskip("distributed")

SHAPE = (16, 16, 32)
TRUTH = {"diffuse": [0.1, 0.06, 0.02], "f0": [0.9, 0.6, 0.3], "alpha": 0.12}
FAST = {"subsample": 400, "seed": 0}


@pytest.fixture(scope="module")
def table_bytes(tmp_path_factory):
    from data_formats.merl import synthesize, write_merl

    from brdffit.models.evaluate import evaluate_model

    model = brdffit.get_model("ggx")
    path = tmp_path_factory.mktemp("hostile-batch") / "t.binary"
    write_merl(path, synthesize(lambda wi, wo: np.asarray(evaluate_model(model, TRUTH, wi, wo)),
                                name="t", shape=SHAPE))
    return path.read_bytes()


@pytest.fixture(scope="module")
def client(tmp_path_factory):
    import dask
    from distributed import Client, LocalCluster

    cache = tmp_path_factory.mktemp("xdg-cache")
    with dask.config.set(runner.LOCAL_SCHEDULER):
        cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                               dashboard_address=None, silence_logs=40,
                               env={"XDG_CACHE_HOME": str(cache)})
    with cluster, Client(cluster) as c:
        yield c


def _everything(folder):
    return sorted(str(p.relative_to(folder)) for p in Path(folder).rglob("*"))


# --- names from data never leave the output folder --------------------------------------------

@pytest.mark.parametrize("name", ["..", ".", "../x", "a/b", "/etc", "", ".hidden", "x\0y",
                                  "\udcff\udcfe", "é" * 200, "a\\b", "-", "x" * 2**20])
def test_safe_name_is_one_plain_component(name):
    safe = inputs.safe_name(name)
    assert outdir.check_component(safe) == safe
    assert not safe.startswith(".") and "/" not in safe and "\\" not in safe
    assert 0 < len(safe.encode("utf-8")) <= inputs.NAME_MAX_BYTES


@pytest.mark.parametrize("name", ["..", ".", "", "a/b", "../x", "x\0"])
def test_unsafe_components_are_refused(name):
    with pytest.raises(outdir.BatchOutputError, match="one plain name"):
        outdir.check_component(name)


def test_a_table_named_dotdot_is_written_inside_the_outdir(client, table_bytes, tmp_path):
    """The reproducer: ``...binary`` has the stem ``..``; a table in memory named ``../x``."""
    from data_formats.merl import read_merl

    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "...binary").write_bytes(table_bytes)
    table = read_merl(tmp_path / "data" / "...binary")
    table.name = "../x"
    (tmp_path / "box").mkdir()
    out = tmp_path / "box" / "out"
    df = brdffit.fit_many([tmp_path / "data" / "...binary", table], "ggx", client=client,
                          outdir=out, **FAST)
    assert df["success"].all(), df["message"].tolist()
    assert df["material"].tolist() == ["__", "___x"]
    assert _everything(tmp_path / "box") == ["out", *sorted(
        f"out/{p}" for p in ["__", "__/ggx.json", "__/ggx.meta.json", "___x", "___x/ggx.json",
                             "___x/ggx.meta.json", "results.csv", "results.parquet"])]
    assert sorted(os.listdir(tmp_path)) == ["box", "data"]


# --- links and special files in the output tree --------------------------------------------------

def test_a_material_folder_that_is_a_link_is_refused_before_any_work(client, table_bytes,
                                                                       tmp_path):
    (tmp_path / "m.binary").write_bytes(table_bytes)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (tmp_path / "out").mkdir()
    (tmp_path / "out" / "m").symlink_to(elsewhere)
    with pytest.raises(outdir.BatchOutputError, match=r"out/m: is a symbolic link"):
        brdffit.fit_many([tmp_path / "m.binary"], "ggx", client=client, outdir=tmp_path / "out",
                         **FAST)
    assert os.listdir(elsewhere) == []
    assert sorted(os.listdir(tmp_path / "out")) == ["m"]  # no table, no result, no probe


@pytest.mark.parametrize("where", ["m/ggx.json", "m/ggx.meta.json", "results.csv"])
@pytest.mark.parametrize("kind", ["link", "fifo"])
def test_a_result_file_that_is_a_link_or_fifo_is_refused(table_bytes, tmp_path, where, kind):
    """Checked by :func:`outdir.prepare` (run_batch calls it before the cluster starts)."""
    target = tmp_path / "victim.json"
    target.write_text("{}")
    (tmp_path / "out" / "m").mkdir(parents=True)
    path = tmp_path / "out" / where
    path.symlink_to(target) if kind == "link" else os.mkfifo(path)
    what = "a symbolic link" if kind == "link" else "a FIFO"
    with pytest.raises(outdir.BatchOutputError, match=f"{where}: is {what}"):
        outdir.prepare(tmp_path / "out", {"m": ["ggx.json", "ggx.meta.json"]})
    assert target.read_text() == "{}"


def test_a_link_planted_during_the_batch_is_never_followed(tmp_path):
    """After the check: the folder is opened without following links, files are renamed into
    place (a link at the name is refused, never written through), reads do not follow."""
    victim = tmp_path / "victim"
    victim.mkdir()
    (victim / "ggx.json").write_text("precious")
    out = tmp_path / "out"
    out.mkdir()
    (out / "m").symlink_to(victim)
    with pytest.raises(outdir.BatchOutputError, match=r"out/m: is a symbolic link"):
        with outdir.Folder.open(out, "m", create=True):
            pass
    (out / "m").unlink()
    with outdir.Folder.open(out, "m", create=True) as folder:
        os.symlink(victim / "ggx.json", out / "m" / "ggx.json")
        assert folder.read("ggx.json") is None and not folder.is_file("ggx.json")
        with pytest.raises(outdir.BatchOutputError, match="ggx.json: is a symbolic link"):
            folder.write("ggx.json", b"evil")
        os.symlink(victim / "ggx.json", out / "m" / ".ggx.json.dead.json")
        folder.remove([".ggx.json.*"])
        folder.write("ggx.meta.json", b"{}")
    assert (victim / "ggx.json").read_text() == "precious" and os.listdir(victim) == ["ggx.json"]
    assert sorted(os.listdir(out / "m")) == ["ggx.json", "ggx.meta.json"]
    assert (out / "m" / "ggx.json").is_symlink()  # left for the user; the next batch refuses it


# --- lists of paths -------------------------------------------------------------------------------

def _main(capsys, *args):
    from brdffit.cli import main

    code = main(["batch", *map(str, args)])
    err = capsys.readouterr().err
    return code, err


def test_a_list_that_is_not_utf8_is_one_line_exit_2(tmp_path, capsys):
    listing = tmp_path / "list.txt"
    listing.write_bytes(b"\xff\xfeshiny.binary\n")
    code, err = _main(capsys, listing, "-m", "ggx", "-o", tmp_path / "out")
    assert code == 2 and err.count("\n") == 1
    assert "list.txt, line 1: not UTF-8 text (byte 0xff at column 1)" in err
    assert not (tmp_path / "out").exists()


def test_a_list_with_bom_and_crlf_is_read(table_bytes, tmp_path):
    (tmp_path / "a.binary").write_bytes(table_bytes)
    (tmp_path / "list.txt").write_bytes(b"\xef\xbb\xbfa.binary\r\n# c\r\n")
    assert inputs.expand([str(tmp_path / "list.txt")]) == [str(tmp_path / "a.binary")]


def test_a_list_larger_than_the_limit_is_refused_before_it_is_read(tmp_path, capsys):
    big = tmp_path / "list.txt"
    with open(big, "wb") as f:  # sparse: takes no disk space
        f.truncate(inputs.LIST_MAX_BYTES + 1)
    code, err = _main(capsys, big, "-m", "ggx", "-o", tmp_path / "out")
    assert code == 2 and err.count("\n") == 1
    assert f"holds at most {inputs.LIST_MAX_BYTES:,} bytes" in err


@pytest.mark.parametrize("body, message", [
    (b"a" * 5000 + b"\n", "line 1: longer than 4096 bytes"),
    (b"# a comment\nx\0y\n", "line 2: contains a NUL byte"),
])
def test_a_list_line_that_cannot_be_a_path_is_refused(tmp_path, body, message):
    (tmp_path / "list.txt").write_bytes(body)
    with pytest.raises(BatchInputError, match=message):
        inputs.expand([str(tmp_path / "list.txt")])


# --- scheduler addresses and the output folder, checked before any work ---------------------------

@pytest.mark.parametrize("address, message", [
    ("foo", "missing port number"),
    ("inproc://x", "scheme 'inproc://' is not supported"),
    ("tcp://[::1", "ipv6 needs brackets"),
    ("ucx://127.0.0.1:1", "scheme 'ucx://' is not supported"),
    ("tcp://127.0.0.1:99999", "port 99999 is not 1 to 65535"),
    ("tcp://127.0.0.1:http", "port is not a number"),
    ("tcp://:1", "host ''"),
])
def test_scheduler_addresses_are_checked_in_one_line(tmp_path, capsys, monkeypatch, address,
                                                     message):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "t.binary").write_bytes(b"never read")
    code, err = _main(capsys, "t.binary", "-m", "ggx", "-o", "out", "--scheduler", address)
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"brdffit batch: error: --scheduler {address!r}: ") and message in err
    assert not (tmp_path / "out").exists()
    monkeypatch.setenv("DASK_SCHEDULER_ADDRESS", address)
    code, err = _main(capsys, "t.binary", "-m", "ggx", "-o", "out")
    assert code == 2 and f"DASK_SCHEDULER_ADDRESS {address!r}: " in err


@pytest.mark.parametrize("args, message", [
    (["--dashboard=foo"], "--dashboard 'foo': not an address HOST:PORT"),
    (["--dashboard", "--scheduler", "tcp://127.0.0.1:1"], "only a local cluster"),
])
def test_dashboard_address_is_checked(tmp_path, capsys, monkeypatch, args, message):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "t.binary").write_bytes(b"never read")
    code, err = _main(capsys, "t.binary", "-m", "ggx", "-o", "out", *args)
    assert code == 2 and err.count("\n") == 1 and message in err
    assert not (tmp_path / "out").exists()


def _read_only(folder):
    """Make ``folder`` read-only even for root (the immutable attribute), or skip."""
    if os.geteuid() != 0:
        folder.chmod(0o555)
        return lambda: folder.chmod(0o755)
    done = subprocess.run(["chattr", "+i", str(folder)], capture_output=True)
    if done.returncode != 0:
        pytest.skip("cannot make a folder read-only for root here (chattr +i)")
    return lambda: subprocess.run(["chattr", "-i", str(folder)], check=True)


def test_a_read_only_outdir_is_refused_before_any_fit(table_bytes, tmp_path, capsys,
                                                       monkeypatch):
    def no_cluster(*args, **kwargs):
        raise AssertionError("the cluster started although OUTDIR cannot be written")

    monkeypatch.setattr(runner, "open_client", no_cluster)
    (tmp_path / "t.binary").write_bytes(table_bytes)
    out = tmp_path / "out"
    out.mkdir()
    undo = _read_only(out)
    try:
        code, err = _main(capsys, tmp_path / "t.binary", "-m", "ggx", "-o", out)
    finally:
        undo()
    assert code == 2 and err.count("\n") == 1
    assert f"{out}: cannot write into the output folder (" in err and ".brdffit" not in err
    assert os.listdir(out) == []


# --- the local cluster: closed to other users, no HTTP server -------------------------------------

def _listening(pid):
    import psutil

    return {c.laddr.port for c in psutil.Process(pid).net_connections("tcp")
            if c.status == psutil.CONN_LISTEN}


def _refused_without_credentials(host, port, context):
    """Whether the scheduler at ``host:port`` refuses a TLS client with ``context``."""
    try:
        with socket.create_connection((host, port), timeout=5) as raw, \
                context.wrap_socket(raw) as tls:
            tls.sendall(b"\0" * 64)
            return tls.recv(1) == b""
    except (ssl.SSLError, OSError):
        return True


def test_local_cluster_refuses_other_clients_and_serves_no_http(tmp_path):
    from distributed import Client
    from distributed.comm.addressing import parse_host_port
    from distributed.security import Security

    before = _listening(os.getpid())  # this process also runs the module's cluster
    with runner.open_client(workers=1) as (client, _):
        address = client.scheduler.address
        assert client.submit(pow, 2, 5).result() == 32  # the batch's own client works
        assert address.startswith("tls://127.0.0.1:")
        host, port = parse_host_port(address)
        with pytest.raises(OSError):  # a plain TCP client (the old open door)
            Client(address.replace("tls://", "tcp://"), timeout="3s")
        anonymous = ssl.create_default_context()
        anonymous.check_hostname, anonymous.verify_mode = False, ssl.CERT_NONE
        assert _refused_without_credentials(host, port, anonymous)
        stranger = Security.temporary()  # valid TLS credentials, but not this batch's
        with pytest.raises(OSError):
            Client(address, security=stranger, timeout="3s")
        # Listening: the scheduler, the nanny and the worker's comms; no HTTP server at all.
        info = client.scheduler_info()
        assert all(a.startswith("tls://127.0.0.1:") and w["nanny"].startswith("tls://127.0.0.1:")
                   for a, w in info["workers"].items())  # every door needs the credentials
        comms = {port} | {parse_host_port(a)[1] for a in info["workers"]}
        comms |= {parse_host_port(w["nanny"])[1] for w in info["workers"].values()}
        pids = [os.getpid(), *client.run(os.getpid).values()]
        assert set().union(*map(_listening, pids)) - before <= comms
        # No node ever opened an HTTP server (not even one closed later): none has a
        # "dashboard" service, which Dask records as soon as it listens.
        assert "dashboard" not in info["services"]
        assert all("dashboard" not in w.get("services", {}) for w in info["workers"].values())
        assert client.run(lambda dask_worker: dask_worker.http_server) == {
            a: None for a in info["workers"]}


def test_a_dashboard_is_served_only_when_asked_for():
    import urllib.request

    with runner.open_client(workers=1, dashboard="127.0.0.1:0") as (client, _):
        port = client.scheduler_info()["services"]["dashboard"]
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=10) as r:
            assert r.status == 200 and r.read() == b"ok"


SIGNAL_EXIT = """
import os
from brdffit.batch import runner

if __name__ == "__main__":
    with runner.open_client(workers=1) as (client, _):
        print(*client.run(os.getpid).values(), flush=True)
        runner.close_local_clusters()  # what the signal watcher of `brdffit batch` runs
        os._exit(130)
"""


def test_closing_the_cluster_on_a_signal_leaks_nothing(tmp_path):
    """The signal watcher ends the process with ``os._exit``: before it, the workers are
    stopped and the cluster closed, so no worker outlives the batch and ``multiprocessing``
    finds no leaked semaphore (without this it warns of them at every interrupted batch), and
    the cluster's scratch space goes with it (before: Dask's worker lock files stayed in the
    temporary folder)."""
    import psutil

    script = tmp_path / "interrupted.py"
    script.write_text(SIGNAL_EXIT)
    (tmp_path / "tmp").mkdir()
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parent.parent),
           "TMPDIR": str(tmp_path / "tmp")}
    done = subprocess.run([sys.executable, str(script)], capture_output=True, text=True,
                          env=env, timeout=120)
    assert done.returncode == 130, done.stderr
    assert "leaked" not in done.stderr and "Traceback" not in done.stderr, done.stderr
    worker = int(done.stdout.split()[0])
    gone = not psutil.pid_exists(worker) or psutil.Process(worker).status() == "zombie"
    assert gone
    assert list((tmp_path / "tmp").iterdir()) == []


@pytest.mark.parametrize("workers", ["0", "-3", "100000"])
def test_the_number_of_local_workers_is_ranged(tmp_path, capsys, workers):
    """``--workers 100000`` tried to start that many processes."""
    from brdffit.cli import main

    code = main(["batch", str(tmp_path / "a.csv"), "-m", "ggx", "-o", str(tmp_path / "out"),
                 "--workers", workers])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "from 1 to 256" in err, err
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("workers", [0, 257, 2.5, True])
def test_fit_many_ranges_its_local_workers(workers):
    from brdffit.errors import ConfigError

    with pytest.raises(ConfigError, match="from 1 to 256"), runner.open_client(workers=workers):
        pass

"""Who may talk to a robot: loopback by default, CURVE with an allow-list otherwise (docs/robot.md, "Keys").

``drivenav robot keys DIR`` writes pyzmq certificate files: ``DIR/server.key`` and ``DIR/server.key_secret`` (the
robot's pair), ``DIR/client.key`` and ``DIR/client.key_secret`` (the brain's pair) and the allow-list
``DIR/authorized/client.key``; the secrets are readable by their owner only (mode 0600). The robot takes its secret
and every public key in ``DIR/authorized/``; the brain takes its secret and ``DIR/server.key``. Copy only what each
side needs onto it.
"""

from __future__ import annotations

import ipaddress
import os
import shutil
import socket
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zmq
import zmq.auth
from zmq.auth.thread import ThreadAuthenticator

from drivenav.errors import InputError

SERVER, CLIENT, AUTHORIZED = "server", "client", "authorized"


def write_keys(directory: Path) -> list[Path]:
    """Create the server and client key pairs and the allow-list in ``directory``; returns the files written.

    An existing key is never overwritten (an :class:`InputError` names it): a robot's keys are replaced on purpose,
    by removing them first.
    """
    directory.mkdir(parents=True, exist_ok=True)
    for name in (f"{SERVER}.key", f"{SERVER}.key_secret", f"{CLIENT}.key", f"{CLIENT}.key_secret"):
        if (directory / name).exists():
            raise InputError(directory / name, "DIR", "a folder without keys (remove old keys on purpose)", "exists")
    written = []
    for name in (SERVER, CLIENT):
        public, secret = (Path(p) for p in zmq.auth.create_certificates(str(directory), name))
        os.chmod(secret, 0o600)
        written += [public, secret]
    authorized = directory / AUTHORIZED
    authorized.mkdir(exist_ok=True)
    written.append(Path(shutil.copy(directory / f"{CLIENT}.key", authorized / f"{CLIENT}.key")))
    return written


@dataclass(frozen=True)
class KeyPair:
    """A CURVE key pair (Z85-encoded bytes, as pyzmq's certificate files hold them)."""

    public: bytes
    secret: bytes


def _secret_pair(path: Path, option: str) -> KeyPair:
    if not path.is_file():
        raise InputError(path, option, "a key folder written by 'drivenav robot keys' (its secret key file)")
    try:
        public, secret = zmq.auth.load_certificate(str(path))
    except (ValueError, OSError) as error:
        raise InputError(path, option, "a pyzmq certificate with a secret key", str(error)) from None
    if secret is None:
        raise InputError(path, option, "a certificate holding a secret key", "a public key only")
    return KeyPair(public, secret)


def server_keys(directory: Path) -> KeyPair:
    """The robot's key pair from ``directory`` (``--keys``); its allow-list must hold at least one key."""
    pair = _secret_pair(directory / f"{SERVER}.key_secret", "--keys")
    if not any((directory / AUTHORIZED).glob("*.key")):
        raise InputError(directory / AUTHORIZED, "--keys", "an allow-list with at least one client public key")
    return pair


def client_keys(directory: Path, option: str = "--robot-keys") -> tuple[KeyPair, bytes]:
    """The client's key pair and the server's public key from ``directory`` (``option``: ``--robot-keys`` for the
    brain, ``--detector-keys`` for a served grounder's client)."""
    pair = _secret_pair(directory / f"{CLIENT}.key_secret", option)
    server_file = directory / f"{SERVER}.key"
    if not server_file.is_file():
        raise InputError(server_file, option, "the server's public key file server.key")
    server_public, _ = zmq.auth.load_certificate(str(server_file))
    return pair, server_public


def is_loopback(address: str) -> bool:
    """Whether a ``tcp://HOST:PORT`` (or ``ipc://``, ``inproc://``) endpoint stays on this machine."""
    if not address.startswith("tcp://"):
        return address.startswith(("ipc://", "inproc://"))
    host = address[len("tcp://") :].rsplit(":", 1)[0].strip("[]")
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return _resolves_to_loopback(host)


def _resolves_to_loopback(host: str) -> bool:
    try:
        infos = socket.getaddrinfo(host, None)
    except OSError:
        return False
    return bool(infos) and all(ipaddress.ip_address(str(info[4][0])).is_loopback for info in infos)


def check_endpoint(address: str, option: str, bind: bool = False) -> None:
    """Refuse, before any socket is made, an endpoint that is not ``tcp://HOST:PORT`` with a port in 1-65535 (``*``
    for a free one, when binding), ``ipc://PATH`` or ``inproc://NAME`` (libzmq would bind an out-of-range port as
    a random one, silently)."""
    scheme, _, rest = address.partition("://")
    if scheme in ("ipc", "inproc") and rest:
        return
    host, _, port = rest.rpartition(":")
    in_range = port.isdigit() and 1 <= int(port) <= 65535
    if scheme != "tcp" or not host or not (in_range or (bind and port == "*")):
        ports = "1-65535 (or * for a free port)" if bind else "1-65535"
        raise InputError("command line", option, f"an endpoint tcp://HOST:PORT with PORT {ports}", address)


def check_bind(address: str, keys: Path | None) -> None:
    """Refuse a malformed endpoint, and to serve on a non-loopback address without CURVE keys (one line, exit 2)."""
    check_endpoint(address, "--bind", bind=True)
    if keys is None and not is_loopback(address):
        raise InputError(
            "command line",
            "--keys",
            "a key folder (drivenav robot keys DIR) to bind a non-loopback address: CURVE is required off this host",
            address,
        )


def secure_server(context: zmq.Context[Any], sock: zmq.Socket[Any], directory: Path) -> ThreadAuthenticator:
    """Make ``sock`` a CURVE server that admits only the public keys in ``directory/authorized``; returns the
    running authenticator (stop it when the socket closes)."""
    pair = server_keys(directory)
    auth = ThreadAuthenticator(context)
    auth.start()
    auth.configure_curve(domain="*", location=str(directory / AUTHORIZED))
    sock.curve_secretkey = pair.secret
    sock.curve_publickey = pair.public
    sock.curve_server = True
    return auth


def secure_client(sock: zmq.Socket[Any], directory: Path, option: str = "--robot-keys") -> None:
    """Make ``sock`` a CURVE client with the client's key pair, trusting only the server's public key (``option``
    names the keys in errors)."""
    pair, server_public = client_keys(directory, option)
    sock.curve_secretkey = pair.secret
    sock.curve_publickey = pair.public
    sock.curve_serverkey = server_public

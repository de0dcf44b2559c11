"""The real-time simulator server behind ``chaser-bt sitl``: the simulator on loopback UDP and TCP.

Sim time is paced to wall time times ``speedup``. This loop is the one place in ``sitl/`` that
reads wall time, through the injected ``monotonic`` callable; the simulator itself only counts
steps. Between steps the loop sleeps in a :mod:`selectors` wait (short timeouts; no descriptor
limit, unlike ``select()``), pulling arriving bytes into the ports' buffers and accepting TCP
clients and UDP peers, each a link of its own; a step reads those buffers, exactly as in-process.
Clients beyond ``max_clients`` (TCP) or peers beyond it (UDP) are refused and counted in the log.

If the machine cannot keep up with ``speedup``, the sim runs as fast as it can and the pacing
re-anchors (logged once) instead of trying to catch up in a burst.

With a signing key (``chaser-bt sitl --signing-key FILE``) the vehicle signs its MAVLink and obeys
only correctly signed messages, as an ArduCopter with a stored key does
(:meth:`sitl.vehicle.mavlink_endpoint.MavlinkEndpoint.enable_signing`).
"""

from __future__ import annotations

import logging
import selectors
import signal
import threading
import time
from typing import Callable

from chaser_bt.vehicle.signing import SigningConfig
from sitl.simulator import Simulator
from sitl.transports import LOOPBACK, TcpClientPort, TcpServer, UdpPeer, UdpPort
from sitl.world.scenario import Scenario

__all__ = ["serve"]

log = logging.getLogger(__name__)

_MAX_WAIT_S = 0.05  # longest select() sleep: bounds how late a stop request is noticed
_MAX_CATCHUP_STEPS = 200  # steps in one go before re-anchoring the pacing


def serve(
    scenario: Scenario,
    *,
    seed: int = 0,
    speedup: float = 1.0,
    udp_port: int = 14550,
    tcp_port: int = 5760,
    ready: Callable[[list[str]], None] | None = None,
    stop: threading.Event | None = None,
    monotonic: Callable[[], float] = time.monotonic,
    physics_hz: float | None = None,
    signing: SigningConfig | None = None,
    max_clients: int = 32,
    radar_sign: Callable[[bytes], bytes] | None = None,
) -> bool:
    """Run the simulator in real time (times ``speedup``) until ``stop`` is set, Ctrl-C or SIGTERM.

    Returns True when Ctrl-C or SIGTERM ended it (the command exits 130), False when ``stop`` was set.

    Args:
        scenario: what to simulate.
        seed: the simulator's seed.
        speedup: sim seconds per wall second.
        udp_port, tcp_port: loopback ports (0 = any free port; the real ones go to ``ready``).
        ready: called once, when listening, with the pymavlink connection strings for clients.
        stop: set it (from another thread) to end the loop.
        monotonic: the wall clock.
        physics_hz: physics rate (default: the simulator's).
        signing: MAVLink 2 signing key and link id (``SigningConfig.from_file(path)``); None: off.
        max_clients: TCP clients, and UDP peers, served at once; more are refused.
        radar_sign: signs each radar datagram sent over UDP (the ground stream's HMAC, a
            ``StreamSigner.sign``); None: plain.
    """
    if not speedup > 0.0:
        raise ValueError(f"speedup must be > 0, got {speedup}")
    stop = stop if stop is not None else threading.Event()
    sim = Simulator(scenario, seed, physics_hz=physics_hz)
    if radar_sign is not None:
        sim.surroundings.sign_radar_datagrams(radar_sign)
    if signing is not None:
        # Clients stamp with the wall clock: so does the vehicle (ArduPilot: GPS time).
        sim.endpoint.enable_signing(signing, epoch_unix_s=time.time() - sim.time_s)
    udp = UdpPort(udp_port, monotonic=monotonic, max_peers=max_clients)
    tcp = TcpServer(tcp_port, max_clients=max_clients)
    clients: list[TcpClientPort | UdpPeer] = []
    signalled = threading.Event()
    previous_sigterm = _on_sigterm(stop, signalled)
    try:
        urls = [f"tcp:{LOOPBACK}:{tcp.port}", f"udpout:{LOOPBACK}:{udp.port}"]
        log.info("simulating %s at %gx on %s", scenario.name, speedup, ", ".join(urls))
        if ready is not None:
            ready(urls)
        _loop(sim, udp, tcp, clients, speedup, stop, monotonic)
    except KeyboardInterrupt:
        log.info("interrupted")
        signalled.set()
    finally:
        if sim.endpoint.signing is not None:
            c = sim.endpoint.signing.counters
            log.info("signing: %d signed, %d unsigned rejected, %d bad signatures", c.signed,
                     c.unsigned_rejected, c.bad_signature)
        if previous_sigterm is not None:
            signal.signal(signal.SIGTERM, previous_sigterm)
        for client in clients:
            if isinstance(client, TcpClientPort):
                client.close()
        tcp.close()
        udp.close()
        log.info("stopped at sim time %.2f s", sim.time_s)
    return signalled.is_set()


def _on_sigterm(stop: threading.Event, signalled: threading.Event):
    """Make SIGTERM set ``signalled`` and ``stop`` (only possible from the main thread); returns the old handler."""
    if threading.current_thread() is not threading.main_thread():
        return None

    def on_sigterm(signum, frame) -> None:
        signalled.set()
        stop.set()

    return signal.signal(signal.SIGTERM, on_sigterm)


def _loop(
    sim: Simulator,
    udp: UdpPort,
    tcp: TcpServer,
    clients: list[TcpClientPort | UdpPeer],
    speedup: float,
    stop: threading.Event,
    monotonic: Callable[[], float],
) -> None:
    wall0, sim0 = monotonic(), sim.time_s
    warned = False
    with selectors.DefaultSelector() as selector:
        selector.register(udp, selectors.EVENT_READ)
        selector.register(tcp, selectors.EVENT_READ)
        while not stop.is_set():
            target = sim0 + (monotonic() - wall0) * speedup
            steps = 0
            while sim.time_s + 0.5 * sim.dt <= target and steps < _MAX_CATCHUP_STEPS:
                sim.step()
                steps += 1
            if steps == _MAX_CATCHUP_STEPS:
                if not warned:
                    log.warning("cannot keep up with %gx; running as fast as possible", speedup)
                    warned = True
                wall0, sim0 = monotonic(), sim.time_s
            tcp_open = sum(isinstance(c, TcpClientPort) for c in clients)
            for client in [*tcp.accept(tcp_open), *udp.accept()]:
                log.info("%s client %s:%d connected", "tcp" if isinstance(client, TcpClientPort) else "udp", *client.addr)
                clients.append(client)
                sim.attach(client)
                if isinstance(client, TcpClientPort):
                    selector.register(client, selectors.EVENT_READ)
            for client in [c for c in clients if c.closed]:
                log.info("client %s:%d left", *client.addr)
                clients.remove(client)
                sim.detach(client)
                if isinstance(client, TcpClientPort):
                    selector.unregister(client)
            for client in clients:
                if isinstance(client, TcpClientPort):
                    events = selectors.EVENT_READ | (selectors.EVENT_WRITE if client.tx_pending else 0)
                    if selector.get_key(client).events != events:
                        selector.modify(client, events)
            wait = wall0 + (sim.time_s + sim.dt - sim0) / speedup - monotonic()
            for key, events in selector.select(min(max(wait, 0.0), _MAX_WAIT_S)):
                port = key.fileobj
                if port is udp or isinstance(port, TcpClientPort) and events & selectors.EVENT_READ:
                    port.pull()
                if isinstance(port, TcpClientPort) and events & selectors.EVENT_WRITE:
                    port.flush()

"""The real-time simulator server behind ``chaser-bt sitl``: the simulator on loopback UDP and TCP.

Sim time is paced to wall time times ``speedup``. This loop is the one place in ``sitl/`` that
reads wall time, through the injected ``monotonic`` callable; the simulator itself only counts
steps. Between steps the loop sleeps in ``select()`` (short timeouts), pulling arriving bytes into
the ports' buffers and accepting TCP clients; a step reads those buffers, exactly as in-process.

If the machine cannot keep up with ``speedup``, the sim runs as fast as it can and the pacing
re-anchors (logged once) instead of trying to catch up in a burst.

With a signing key (``chaser-bt sitl --signing-key FILE``) the vehicle signs its MAVLink and obeys
only correctly signed messages, as an ArduCopter with a stored key does
(:meth:`sitl.vehicle.mavlink_endpoint.MavlinkEndpoint.enable_signing`).
"""

from __future__ import annotations

import logging
import select
import signal
import threading
import time
from typing import Callable

from chaser_bt.vehicle.signing import SigningConfig
from sitl.simulator import Simulator
from sitl.transports import LOOPBACK, TcpClientPort, TcpServer, UdpPort
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
) -> None:
    """Run the simulator in real time (times ``speedup``) until ``stop`` is set, Ctrl-C or SIGTERM.

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
    """
    if not speedup > 0.0:
        raise ValueError(f"speedup must be > 0, got {speedup}")
    stop = stop if stop is not None else threading.Event()
    sim = Simulator(scenario, seed, physics_hz=physics_hz)
    if signing is not None:
        # Clients stamp with the wall clock: so does the vehicle (ArduPilot: GPS time).
        sim.endpoint.enable_signing(signing, epoch_unix_s=time.time() - sim.time_s)
    udp = UdpPort(udp_port, monotonic=monotonic)
    tcp = TcpServer(tcp_port)
    clients: list[TcpClientPort] = []
    sim.attach(udp)
    previous_sigterm = _on_sigterm(stop)
    try:
        urls = [f"tcp:{LOOPBACK}:{tcp.port}", f"udpout:{LOOPBACK}:{udp.port}"]
        log.info("simulating %s at %gx on %s", scenario.name, speedup, ", ".join(urls))
        if ready is not None:
            ready(urls)
        _loop(sim, udp, tcp, clients, speedup, stop, monotonic)
    except KeyboardInterrupt:
        log.info("interrupted")
    finally:
        if sim.endpoint.signing is not None:
            c = sim.endpoint.signing.counters
            log.info("signing: %d signed, %d unsigned rejected, %d bad signatures", c.signed,
                     c.unsigned_rejected, c.bad_signature)
        if previous_sigterm is not None:
            signal.signal(signal.SIGTERM, previous_sigterm)
        for client in clients:
            client.close()
        tcp.close()
        udp.close()
        log.info("stopped at sim time %.2f s", sim.time_s)


def _on_sigterm(stop: threading.Event):
    """Make SIGTERM set ``stop`` (only possible from the main thread); returns the old handler."""
    if threading.current_thread() is not threading.main_thread():
        return None
    return signal.signal(signal.SIGTERM, lambda signum, frame: stop.set())


def _loop(
    sim: Simulator,
    udp: UdpPort,
    tcp: TcpServer,
    clients: list[TcpClientPort],
    speedup: float,
    stop: threading.Event,
    monotonic: Callable[[], float],
) -> None:
    wall0, sim0 = monotonic(), sim.time_s
    warned = False
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
        for client in tcp.accept():
            log.info("tcp client %s:%d connected", *client.addr)
            clients.append(client)
            sim.attach(client)
        for client in [c for c in clients if c.closed]:
            log.info("tcp client %s:%d left", *client.addr)
            clients.remove(client)
            sim.detach(client)
        wait = wall0 + (sim.time_s + sim.dt - sim0) / speedup - monotonic()
        readers = [udp, tcp, *clients]
        writers = [c for c in clients if c.tx_pending]
        readable, writable, _ = select.select(readers, writers, [], min(max(wait, 0.0), _MAX_WAIT_S))
        for port in readable:
            if port is not tcp:
                port.pull()
        for client in writable:
            client.flush()

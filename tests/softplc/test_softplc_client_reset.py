"""PlcClient: a connection the server resets (RST, as OpenPLC v3's accept race leaves some)
is a ModbusIoError, the broken connection callers reconnect after, not a raw OSError."""

from __future__ import annotations

import socket
import struct
import threading

import pytest

from armbench.softplc.modbus_client import ModbusIoError, PlcClient


def test_a_reset_connection_is_a_modbus_io_error() -> None:
    listener = socket.create_server(("127.0.0.1", 0))
    port = listener.getsockname()[1]

    def reset_after_the_request() -> None:
        conn, _ = listener.accept()
        conn.recv(260)  # the request
        # linger 0: close() sends RST instead of FIN
        conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        conn.close()

    t = threading.Thread(target=reset_after_the_request)
    t.start()
    try:
        with PlcClient("127.0.0.1", port, timeout_s=2.0) as client, \
                pytest.raises(ModbusIoError, match="function 3"):
            client.read_holding_registers(0, 1)
    finally:
        t.join(5.0)
        listener.close()

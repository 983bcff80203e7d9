"""A small Modbus TCP server (function codes 3, 4, 6, 16) over a register bank.

The virtual rig needs registers computed on demand from a running model, a hook on
every write (its watchdog) and, for the fault tests, deliberately late answers.
That is a few dozen lines of the protocol (MBAP header + PDU, Modbus Application
Protocol 1.1b and Messaging on TCP/IP 1.0b), so it is written out here rather than
bent out of pymodbus's server datastore, whose classes 3.16 deprecates
(ModbusDeviceContext, ModbusServerContext: "removed in v4").  A side benefit: the
DAQ backend's pymodbus client is tested against an independent implementation,
as it will be against a LabJack or a PLC.

Like a LabJack T-series, the bank is one address map served on both read codes.
"""

from __future__ import annotations

import asyncio
import struct
from typing import Protocol, Sequence

READ_HOLDING, READ_INPUT, WRITE_SINGLE, WRITE_MULTIPLE = 3, 4, 6, 16
ILLEGAL_FUNCTION, ILLEGAL_ADDRESS, ILLEGAL_VALUE, DEVICE_FAILURE = 1, 2, 3, 4
#: Largest counts one request may carry (protocol limits).
MAX_READ, MAX_WRITE = 125, 123


class IllegalAddress(Exception):
    """A request touched a register the bank does not have (or may not write)."""


class RegisterBank(Protocol):
    def read(self, address: int, count: int) -> list[int]:
        """`count` 16-bit words from `address`; IllegalAddress if any is missing."""

    def write(self, address: int, values: Sequence[int]) -> None:
        """Store words from `address`; IllegalAddress if any may not be written."""


def answer(bank: RegisterBank, pdu: bytes) -> bytes:
    """The response PDU to a request PDU (an exception response for a bad one)."""
    if not pdu:
        return bytes([0x80, ILLEGAL_FUNCTION])
    fc = pdu[0]
    try:
        if fc in (READ_HOLDING, READ_INPUT):
            address, count = struct.unpack(">HH", pdu[1:5])
            if not 1 <= count <= MAX_READ:
                return _exception(fc, ILLEGAL_VALUE)
            words = bank.read(address, count)
            return struct.pack(f">BB{count}H", fc, 2 * count, *words)
        if fc == WRITE_SINGLE:
            address, value = struct.unpack(">HH", pdu[1:5])
            bank.write(address, [value])
            return pdu[:5]
        if fc == WRITE_MULTIPLE:
            address, count, nbytes = struct.unpack(">HHB", pdu[1:6])
            if not 1 <= count <= MAX_WRITE or nbytes != 2 * count or len(pdu) < 6 + nbytes:
                return _exception(fc, ILLEGAL_VALUE)
            bank.write(address, list(struct.unpack(f">{count}H", pdu[6:6 + nbytes])))
            return struct.pack(">BHH", fc, address, count)
    except IllegalAddress:
        return _exception(fc, ILLEGAL_ADDRESS)
    except struct.error:
        return _exception(fc, ILLEGAL_VALUE)
    return _exception(fc, ILLEGAL_FUNCTION)


def _exception(fc: int, code: int) -> bytes:
    return bytes([(fc | 0x80) & 0xFF, code])


class ModbusTcpServer:
    """Serves `bank` to any number of clients; `reply_delay` s before each answer."""

    def __init__(self, bank: RegisterBank, *, reply_delay: float = 0.0) -> None:
        self.bank = bank
        self.reply_delay = reply_delay
        self._server: asyncio.Server | None = None
        self._clients: set[asyncio.Task[None]] = set()

    async def start(self, host: str, port: int) -> tuple[str, int]:
        """Listen; returns the address bound (port 0 picks a free one)."""
        self._server = await asyncio.start_server(self._client, host, port, reuse_address=True)
        sockname = self._server.sockets[0].getsockname()
        return sockname[0], sockname[1]

    async def stop(self) -> None:
        """Stop listening and end every connection: on Python 3.11 closing the server
        leaves its connections' tasks pending, and a loop stopped over them logs "Task
        was destroyed but it is pending" when they are collected (a warning that once
        crashed pytest's summary, CPython's "AST constructor recursion depth mismatch")."""
        if self._server is not None:
            self._server.close()
            for task in list(self._clients):
                task.cancel()
            if self._clients:
                await asyncio.gather(*self._clients, return_exceptions=True)
            await self._server.wait_closed()

    async def _client(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        if task is not None:
            self._clients.add(task)
            task.add_done_callback(self._clients.discard)
        try:
            while True:
                tid, protocol, length, unit = struct.unpack(">HHHB", await reader.readexactly(7))
                if protocol != 0 or not 2 <= length <= 254:
                    break  # not Modbus: drop the connection as devices do
                pdu = await reader.readexactly(length - 1)
                response = answer(self.bank, pdu)
                if self.reply_delay > 0:
                    await asyncio.sleep(self.reply_delay)
                writer.write(struct.pack(">HHHB", tid, 0, len(response) + 1, unit) + response)
                await writer.drain()
        except (asyncio.IncompleteReadError, ConnectionError):
            pass
        finally:
            writer.close()

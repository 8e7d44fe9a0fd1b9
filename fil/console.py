"""A scripted client of the odocal serial console (docs/protocol.md) over any byte stream: the
emulator's USART2 socket, or a file-like serial port.

Every command gets exactly one final line starting with `ok` or `err`; data lines before it are
indented; `event …` and `stream …` lines are unsolicited and collected separately.
"""

import socket
import threading
import time


class ConsoleError(Exception):
    pass


class Console:
    def __init__(self, sock):
        self.sock = sock
        self.buf = b""
        self.events = []
        self.streams = []
        self.transcript = []

    @classmethod
    def unix(cls, path, timeout=10.0):
        deadline = time.time() + timeout
        while True:
            s = socket.socket(socket.AF_UNIX)
            try:
                s.connect(path)
                return cls(s)
            except OSError:
                s.close()
                if time.time() > deadline:
                    raise
                time.sleep(0.02)

    def _fill(self, deadline):
        self.sock.settimeout(max(0.001, deadline - time.time()))
        try:
            chunk = self.sock.recv(65536)
        except socket.timeout:
            return False
        if not chunk:
            raise ConsoleError("the console closed the connection")
        self.buf += chunk
        return True

    def read_line(self, timeout):
        """The next line (without its `\\r\\n`), or None after `timeout` seconds."""
        deadline = time.time() + timeout
        while b"\n" not in self.buf:
            if time.time() >= deadline or not self._fill(deadline):
                return None
        line, self.buf = self.buf.split(b"\n", 1)
        text = line.rstrip(b"\r").decode(errors="replace")
        self.transcript.append(("<", text))
        return text

    def _sort(self, line):
        if line.startswith("event "):
            self.events.append(line)
            return "event"
        if line.startswith("stream "):
            self.streams.append(line)
            return "stream"
        return "reply"

    def wait_event(self, prefix, timeout):
        """Reads until an event line starting with `prefix`; returns it."""
        deadline = time.time() + timeout
        for i, e in enumerate(self.events):
            if e.startswith(prefix):
                return self.events.pop(i)
        while time.time() < deadline:
            line = self.read_line(deadline - time.time())
            if line is None:
                break
            if self._sort(line) == "event" and line.startswith(prefix):
                self.events.pop()
                return line
        raise ConsoleError(f"no `{prefix}` event within {timeout} s")

    def send_raw(self, data):
        self.transcript.append((">", data))
        # The emulated USART takes one byte per receive interrupt: a long burst takes a while.
        self.sock.settimeout(120.0)
        self.sock.sendall(data)

    def send_burst(self, data, chunk=256):
        """Sends `data` while reading what the console answers, and returns those reply lines.

        The emulator writes each transmitted byte to the socket separately, so only a few
        hundred unread bytes block it (and with it its receive side): the burst is sent from a
        second thread while this one keeps reading."""
        errors = []
        sender_sock = self.sock.dup()
        sender_sock.settimeout(120.0)

        def send():
            try:
                for i in range(0, len(data), chunk):
                    sender_sock.sendall(data[i:i + chunk])
            except OSError as e:
                errors.append(e)

        sender = threading.Thread(target=send)
        sender.start()
        got = []
        while sender.is_alive():
            got += self.quiet(0.01)
        sender.join()
        sender_sock.close()
        self.transcript.append((">", data))
        if errors:
            raise ConsoleError(f"burst not accepted: {errors[0]}")
        return got

    def command(self, line, timeout=10.0, ending=b"\r\n"):
        """Sends one line; returns (data lines, final line). Raises on timeout."""
        payload = line if isinstance(line, bytes) else line.encode()
        self.send_raw(payload + ending)
        return self.reply(timeout)

    def reply(self, timeout=10.0):
        """Reads one reply: data lines up to the final `ok …` / `err …` line."""
        data = []
        deadline = time.time() + timeout
        while True:
            rest = deadline - time.time()
            line = self.read_line(rest) if rest > 0 else None
            if line is None:
                raise ConsoleError(f"no final reply within {timeout} s (got {data})")
            if self._sort(line) != "reply":
                continue
            if line.startswith("ok") or line.startswith("err "):
                return data, line
            data.append(line)

    def quiet(self, seconds):
        """Collects whatever arrives within `seconds` (replies to nothing are returned)."""
        got = []
        deadline = time.time() + seconds
        while time.time() < deadline:
            line = self.read_line(deadline - time.time())
            if line is None:
                break
            if self._sort(line) == "reply":
                got.append(line)
        return got

    def ok(self, line, timeout=10.0):
        """Sends `line`; returns (data, final) and raises if the final line is not `ok`."""
        data, final = self.command(line, timeout)
        if not final.startswith("ok"):
            raise ConsoleError(f"`{line}` answered `{final}`")
        return data, final

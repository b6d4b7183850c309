"""The unit file's settings, read as systemd reads them, and its seccomp part rebuilt for a test process.

systemd itself cannot be run in a test, but three of the unit's settings are plain seccomp filters that any process can
install on itself before exec: SystemCallFilter= (with SystemCallErrorNumber=), MemoryDenyWriteExecute= and
RestrictAddressFamilies=. `python -m tests.unit_sandbox PROGRAM_FILE -- COMMAND...` installs a filter written by
`seccomp_program` and execs COMMAND, so the daemon can be run under the unit's filter against the simulator.
x86_64 only: the system call numbers come from the kernel headers.
"""

from __future__ import annotations

import ctypes
import os
import platform
import re
import socket
import struct
import subprocess
import sys
from pathlib import Path

UNISTD_64 = [Path("/usr/include/x86_64-linux-gnu/asm/unistd_64.h"), Path("/usr/include/asm/unistd_64.h")]
AUDIT_ARCH_X86_64 = 0xC000003E
X32_SYSCALL_BIT = 0x40000000

# classic BPF opcodes and seccomp return values (linux/filter.h, linux/seccomp.h)
LD_ABS_W, JEQ, JSET, JGE, RET = 0x20, 0x15, 0x45, 0x35, 0x06
RET_ALLOW, RET_KILL_PROCESS, RET_ERRNO = 0x7FFF0000, 0x80000000, 0x00050000
PROT_WRITE, PROT_EXEC, SHM_EXEC = 0x2, 0x4, 0o100000
PR_SET_NO_NEW_PRIVS, SECCOMP_SET_MODE_FILTER = 38, 1
ERRNO = {"EPERM": 1, "EACCES": 13, "ENOSYS": 38, "EAFNOSUPPORT": 97}


def read_unit(path: Path) -> dict[str, dict[str, list[str]]]:
    """section -> key -> every value assigned, in order (systemd units repeat keys; configparser cannot read them)."""
    sections: dict[str, dict[str, list[str]]] = {}
    current: dict[str, list[str]] = {}
    for raw in path.read_text().splitlines():
        line = raw.strip()
        if not line or line.startswith(("#", ";")):
            continue
        if line.startswith("[") and line.endswith("]"):
            current = sections.setdefault(line[1:-1], {})
            continue
        key, _, value = line.partition("=")
        current.setdefault(key.strip(), []).append(value.strip())
    return sections


def syscall_groups() -> dict[str, list[str]]:
    """`systemd-analyze syscall-filter`: each @group with its members (system calls and other @groups)."""
    out = subprocess.run(["systemd-analyze", "syscall-filter"], capture_output=True, text=True, check=True).stdout
    groups: dict[str, list[str]] = {}
    members: list[str] | None = None
    for raw in out.splitlines():
        line = raw.strip()
        if not line or line.startswith("#"):
            continue
        if not raw.startswith((" ", "\t")) and line.startswith("@"):
            members = groups.setdefault(line, [])
        elif members is not None:
            members.append(line)
    return groups


def expand(names: list[str], groups: dict[str, list[str]]) -> set[str]:
    result: set[str] = set()
    for name in names:
        result |= expand(groups[name], groups) if name.startswith("@") else {name}
    return result


def allowed_syscalls(filters: list[str], groups: dict[str, list[str]]) -> set[str]:
    """SystemCallFilter= lines as systemd combines them: the first one is an allow list (it must not start with ~ for
    this helper), a later ~ line takes its calls out, a later plain line puts calls in. No lines: every call."""
    if not filters:
        return {name for members in groups.values() for name in members if not name.startswith("@")} | set(
            syscall_numbers() or {}
        )
    if filters[0].startswith("~"):
        raise ValueError(f"expected an allow list first, got {filters}")
    allowed: set[str] = set()
    for line in filters:
        deny = line.startswith("~")
        calls = expand(line.lstrip("~").split(), groups)
        allowed = allowed - calls if deny else allowed | calls
    return allowed


def syscall_numbers() -> dict[str, int] | None:
    if platform.machine() != "x86_64":
        return None
    for header in UNISTD_64:
        if header.exists():
            return {m[1]: int(m[2]) for m in re.finditer(r"#define __NR_(\w+)\s+(\d+)", header.read_text())}
    return None


def seccomp_program(
    allowed: set[str],
    numbers: dict[str, int],
    error: str = "EPERM",
    deny_write_execute: bool = True,
    address_families: set[int] | None = None,
) -> bytes:
    """A seccomp filter doing what systemd's does for the same settings: calls outside `allowed` fail with `error`;
    with `deny_write_execute`, mmap() of memory both writable and executable, mprotect()/pkey_mprotect() adding
    PROT_EXEC and shmat(SHM_EXEC) fail with EPERM (systemd's MemoryDenyWriteExecute=); socket() of a family outside
    `address_families` fails with EAFNOSUPPORT (RestrictAddressFamilies=)."""

    def arg(i: int) -> int:  # offset of the low 32 bits of args[i] in struct seccomp_data (little endian)
        return 16 + 8 * i

    eperm = RET_ERRNO | ERRNO["EPERM"]
    p: list[tuple[int, int, int, int]] = [
        (LD_ABS_W, 0, 0, 4),
        (JEQ, 1, 0, AUDIT_ARCH_X86_64),
        (RET, 0, 0, RET_KILL_PROCESS),
        (LD_ABS_W, 0, 0, 0),
        (JGE, 0, 1, X32_SYSCALL_BIT),
        (RET, 0, 0, eperm),
    ]
    if deny_write_execute:
        p += [(LD_ABS_W, 0, 0, 0), (JEQ, 0, 4, numbers["mmap"]), (LD_ABS_W, 0, 0, arg(2))]
        p += [(JSET, 0, 2, PROT_WRITE), (JSET, 0, 1, PROT_EXEC), (RET, 0, 0, eperm)]
        for name, flag in (("mprotect", PROT_EXEC), ("pkey_mprotect", PROT_EXEC), ("shmat", SHM_EXEC)):
            p += [(LD_ABS_W, 0, 0, 0), (JEQ, 0, 3, numbers[name]), (LD_ABS_W, 0, 0, arg(2))]
            p += [(JSET, 0, 1, flag), (RET, 0, 0, eperm)]
    if address_families is not None:
        families = sorted(address_families)
        p += [(LD_ABS_W, 0, 0, 0), (JEQ, 0, len(families) + 2, numbers["socket"]), (LD_ABS_W, 0, 0, arg(0))]
        p += [(JEQ, len(families) - i, 0, f) for i, f in enumerate(families)]
        p += [(RET, 0, 0, RET_ERRNO | ERRNO["EAFNOSUPPORT"])]
    p.append((LD_ABS_W, 0, 0, 0))
    for nr in sorted(numbers[name] for name in allowed if name in numbers):
        p += [(JEQ, 0, 1, nr), (RET, 0, 0, RET_ALLOW)]
    p.append((RET, 0, 0, RET_ERRNO | ERRNO[error]))
    return b"".join(struct.pack("HBBI", *ins) for ins in p)


def unit_seccomp_program(unit: Path) -> bytes | None:
    """The unit's SystemCallFilter=, SystemCallErrorNumber=, MemoryDenyWriteExecute= and RestrictAddressFamilies= as
    one filter, or None where this machine cannot build it (not x86_64, no kernel headers, no systemd-analyze)."""
    numbers = syscall_numbers()
    if numbers is None:
        return None
    try:
        groups = syscall_groups()
    except (OSError, subprocess.CalledProcessError):
        return None
    service = read_unit(unit)["Service"]
    families = None
    if "RestrictAddressFamilies" in service:
        families = {int(getattr(socket, name)) for name in " ".join(service["RestrictAddressFamilies"]).split()}
    return seccomp_program(
        allowed_syscalls(service.get("SystemCallFilter", []), groups),
        numbers,
        error=service.get("SystemCallErrorNumber", ["EPERM"])[-1],
        deny_write_execute=service.get("MemoryDenyWriteExecute", ["no"])[-1] == "yes",
        address_families=families,
    )


class _SockFprog(ctypes.Structure):
    _fields_ = [("len", ctypes.c_ushort), ("filter", ctypes.c_void_p)]


def install(program: bytes) -> None:
    numbers = syscall_numbers()
    assert numbers is not None, "x86_64 kernel headers needed"
    libc = ctypes.CDLL(None, use_errno=True)
    buf = ctypes.create_string_buffer(program, len(program))
    prog = _SockFprog(len(program) // 8, ctypes.addressof(buf))
    if libc.prctl(PR_SET_NO_NEW_PRIVS, 1, 0, 0, 0) != 0:
        raise OSError(ctypes.get_errno(), "prctl(PR_SET_NO_NEW_PRIVS)")
    if libc.syscall(numbers["seccomp"], SECCOMP_SET_MODE_FILTER, 0, ctypes.byref(prog)) != 0:
        raise OSError(ctypes.get_errno(), "seccomp(SECCOMP_SET_MODE_FILTER)")


if __name__ == "__main__":
    program_file, separator, *command = sys.argv[1:]
    assert separator == "--" and command, "usage: python -m tests.unit_sandbox PROGRAM_FILE -- COMMAND..."
    install(Path(program_file).read_bytes())
    os.execv(command[0], command)

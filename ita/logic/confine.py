"""The operating system's walls around the process that runs a user's goal.

The Prolog checks of a user goal (``goal_hazard/2``, ``library(sandbox)``) are a deny
list, and a deny list loses a race now and then.  The walls here hold on their own, for
a goal that got past every Prolog check:

- **bubblewrap** (Debian's ``bubblewrap``, the unprivileged sandbox of Flatpak) starts
  ``swipl`` in new namespaces: a mount namespace that holds only SWI-Prolog (its binary,
  the shared libraries it loads, its own library) and the project's ``prolog/`` and
  ``kb/`` directories (under ``/ita``, not at their own paths, so that not even the names
  of the directories above them are seen), all read-only, on a read-only root (no
  ``/etc``, no ``/proc``, no ``/dev``, no home directory, no temporary directory, no
  shell to run); a PID namespace,
  so every process inside dies with it (``--die-with-parent``: when the caller kills
  bwrap, the kernel kills the whole namespace); a network namespace with no interface but
  its own loopback; a user namespace with no capability, the goal running as ``nobody``;
  its own IPC and UTS namespaces and session.
- **seccomp**, installed by bwrap just before it starts ``swipl`` (the filter is made by
  libseccomp through ``pyseccomp``): no new process or thread (``fork``, ``vfork``,
  ``clone``, ``clone3``), no other program (``execveat``; ``execve`` finds nothing to run
  but ``swipl`` in the mount namespace), no socket, no file opened for writing or
  created, no directory made, nothing renamed, linked, deleted or changed in mode, owner
  or times, no ``ptrace``, ``mount``, namespace, BPF, keyring or ``io_uring`` call.
  Denied calls fail with ``EPERM`` (or ``EACCES`` for an open for writing, ``ENOSYS``
  for ``clone3`` and ``openat2``); a system call of another ABI kills the process.
- **rlimits**, set before bwrap starts: CPU time, 1 GiB of address space, no byte
  written to a file, few open files, no core dump (see :func:`set_limits`).
- **a user of no rights**: when ITA runs as root the process becomes ``nobody`` before
  bwrap starts (when ``nobody`` can read the files it needs), so even outside the user
  namespace it holds no right of root's.

Why bubblewrap and not Landlock or seccomp alone: Landlock restricts files and (since
ABI 4) TCP ports, but cannot hide the rest of the file system's names, make a PID
namespace or stop a process from forking; seccomp alone sees system calls, not paths.
bubblewrap does the namespaces that the kernel offers to unprivileged users, is a small,
audited setuid-free program shipped by Debian, and takes a seccomp program to install
as its last step, so one well-kept mechanism gives every wall.  Where the kernel offers
no unprivileged user namespaces (and ITA does not run as root), bwrap cannot start and
``ita kb query`` refuses to run, saying why (:class:`Unconfinable`): it never runs a
goal without its walls.
"""

from __future__ import annotations

import errno
import os
import pwd
import re
import shutil
import stat
import subprocess
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ita.errors import ItaError

__all__ = ["Unconfinable", "Jail", "RLimits", "set_limits", "seccomp_program", "namespace_pid",
           "await_namespace_end"]

NOBODY_ID = 65534  # the uid and gid the goal has inside its user namespace
INSIDE = "/ita"    # where the project's directories are seen inside the jail

# System calls a goal's process never needs; each fails with EPERM.
DENIED = (
    # new processes and programs
    "fork", "vfork", "clone", "execveat",
    # the network and local sockets
    "socket", "socketpair", "connect", "bind", "listen", "accept", "accept4",
    "sendto", "sendmsg", "sendmmsg",
    # changes to the file system
    "creat", "mkdir", "mkdirat", "rmdir", "unlink", "unlinkat", "rename", "renameat",
    "renameat2", "link", "linkat", "symlink", "symlinkat", "mknod", "mknodat", "truncate",
    "ftruncate", "chmod", "fchmod", "fchmodat", "chown", "fchown", "lchown", "fchownat",
    "utime", "utimes", "utimensat", "futimesat", "setxattr", "lsetxattr", "fsetxattr",
    "removexattr", "lremovexattr", "fremovexattr", "memfd_create", "name_to_handle_at",
    "open_by_handle_at", "fanotify_init", "inotify_init", "inotify_init1",
    # other processes, the kernel and its namespaces
    "ptrace", "process_vm_readv", "process_vm_writev", "kcmp", "pidfd_open", "pidfd_getfd",
    "mount", "umount2", "pivot_root", "chroot", "unshare", "setns", "bpf",
    "perf_event_open", "userfaultfd", "keyctl", "add_key", "request_key", "acct",
    "io_uring_setup", "io_uring_enter", "io_uring_register", "personality",
    "init_module", "finit_module", "delete_module", "kexec_load", "reboot",
    "swapon", "swapoff", "sethostname", "setdomainname", "quotactl",
)
# Denied with ENOSYS so that a library falls back to the call this filter judges.
UNSUPPORTED = ("clone3", "openat2")
# open(2) flags that write or create: an open with any of them fails with EACCES.
WRITE_FLAGS = (os.O_CREAT, os.O_TRUNC, os.O_APPEND, getattr(os, "O_TMPFILE", 0) & ~os.O_DIRECTORY)


class Unconfinable(ItaError):
    """The walls of a user goal's process cannot be raised on this machine."""


@dataclass(frozen=True)
class RLimits:
    """The resource limits of a confined process (all set as soft = hard)."""

    cpu_seconds: int
    memory_bytes: int
    open_files: int


def set_limits(limits: RLimits) -> None:
    """Set `limits` on this process, and no file writes (``RLIMIT_FSIZE`` 0) and no core
    dump.  Runs in the child between fork and exec."""
    import resource

    resource.setrlimit(resource.RLIMIT_CPU, (limits.cpu_seconds, limits.cpu_seconds))
    resource.setrlimit(resource.RLIMIT_AS, (limits.memory_bytes, limits.memory_bytes))
    resource.setrlimit(resource.RLIMIT_FSIZE, (0, 0))
    resource.setrlimit(resource.RLIMIT_NOFILE, (limits.open_files, limits.open_files))
    resource.setrlimit(resource.RLIMIT_CORE, (0, 0))


def seccomp_program() -> bytes:
    """The seccomp filter of a confined process, as a classic BPF program for this
    machine's system-call ABI (bwrap's ``--seccomp`` takes it)."""
    try:
        import pyseccomp as seccomp
    except (ImportError, OSError) as exc:  # pyseccomp missing, or libseccomp.so.2 not found
        raise Unconfinable(f"cannot make the query process's seccomp filter ({exc}); "
                           "install libseccomp2 and the pyseccomp package") from None
    filt = seccomp.SyscallFilter(defaction=seccomp.ALLOW)
    for name in DENIED:
        _deny(filt, seccomp, seccomp.ERRNO(errno.EPERM), name)
    for name in UNSUPPORTED:
        _deny(filt, seccomp, seccomp.ERRNO(errno.ENOSYS), name)
    refuse = seccomp.ERRNO(errno.EACCES)
    access = os.O_WRONLY | os.O_RDWR
    for syscall, index in (("open", 1), ("openat", 2)):
        for value in (os.O_WRONLY, os.O_RDWR):
            _deny(filt, seccomp, refuse, syscall, seccomp.Arg(index, seccomp.MASKED_EQ, access, value))
        for flag in WRITE_FLAGS:
            if flag:
                _deny(filt, seccomp, refuse, syscall, seccomp.Arg(index, seccomp.MASKED_EQ, flag, flag))
    read, write = os.pipe()
    try:
        with os.fdopen(write, "wb", closefd=False) as sink:
            filt.export_bpf(sink)
        os.close(write)
        write = -1
        chunks = []
        while chunk := os.read(read, 65536):
            chunks.append(chunk)
        return b"".join(chunks)
    finally:
        os.close(read)
        if write >= 0:
            os.close(write)


def _deny(filt: Any, seccomp: Any, action: int, name: str, *args: Any) -> None:
    """Add one rule; a system call this ABI does not have (``fork`` on aarch64) is skipped."""
    if seccomp.resolve_syscall(seccomp.system_arch(), name) < 0:
        return
    filt.add_rule(action, name, *args)


@dataclass(frozen=True)
class Jail:
    """How to start a program behind the walls (see the module's docstring).

    `readable` are SWI-Prolog's directories and files, bound read-only at their own
    paths; `mounts` are the project's directories, each bound read-only under ``/ita``
    where it stands to the others as outside (``kb/`` and ``prolog/`` as ``/ita/kb`` and
    ``/ita/prolog``: their relative paths hold; :meth:`inside`, :meth:`outside` translate); `links` are (target,
    path) symbolic links made inside (the shared libraries' names);
    `user` is the (uid, gid) the process becomes before bwrap starts (``nobody`` when
    ITA runs as root), or None to stay the caller.  Made once by :meth:`find` and used
    for every goal (a `kb shell` session pays for finding it once).
    """

    bwrap: str
    program: str
    readable: tuple[str, ...]
    mounts: tuple[tuple[str, str], ...]
    links: tuple[tuple[str, str], ...]
    user: tuple[int, int] | None
    seccomp: bytes

    @staticmethod
    def find(program: str, directories: Iterable[Path], files: Iterable[Path] = ()) -> "Jail":
        """The jail for `program` (``swipl``, found on PATH or a path) reading
        `directories` (the project's ``prolog/`` and ``kb/``), whose `files` it loads
        (when ITA runs as root, ``nobody`` must be able to read them to be used).

        Raises :class:`Unconfinable` when bubblewrap or the seccomp filter is missing."""
        bwrap = shutil.which("bwrap")
        if bwrap is None:
            raise Unconfinable("bubblewrap (bwrap) is not installed; the knowledge-base queries "
                               "run only behind its walls (Debian: apt-get install bubblewrap; "
                               "`bash setup.sh setup` installs it)")
        found = shutil.which(program)
        if found is None:
            raise ItaError(f"SWI-Prolog ({program}) is not on PATH; it runs the knowledge-base queries")
        real = os.path.realpath(found)
        libraries = _shared_libraries(real)
        home = _prolog_home(real)
        dirs = sorted({os.path.realpath(d) for d in directories})
        readable = tuple(dict.fromkeys([home, *(lib for lib, _ in libraries)]))
        top = os.path.commonpath(dirs) if dirs else "/"
        mounts = tuple((d, os.path.normpath(os.path.join(INSIDE, os.path.relpath(d, top)))) for d in dirs)
        links = tuple(dict.fromkeys((lib, link) for lib, link in libraries if link != lib))
        user = _unprivileged([real, home, *dirs, *(str(f) for f in files)])
        return Jail(bwrap, real, readable, mounts, links, user, seccomp_program())

    def inside(self, path: Path | str) -> str:
        """Where the file `path` of a bound project directory is seen inside the jail."""
        real = os.path.realpath(path)
        for source, target in self.mounts:
            if real == source or real.startswith(source + os.sep):
                return target + real[len(source):]
        raise Unconfinable(f"{path} is in no directory the query process may read")

    def outside(self, text: str) -> str:
        """`text` (a reply of the jailed process) with its paths of the bound project
        directories written as they are outside."""
        for source, target in self.mounts:
            text = text.replace(target + "/", source + "/")
        return text

    def command(self, args: Sequence[str], seccomp_fd: int, env: dict[str, str],
                info_fd: int | None = None) -> list[str]:
        """The bwrap command line that runs the jail's program with `args`; the seccomp
        program is read from `seccomp_fd`, and bwrap writes the PID of the namespace's
        first process to `info_fd` (both inherited by bwrap)."""
        command = [self.bwrap, "--unshare-all", "--unshare-user", "--uid", str(NOBODY_ID),
                   "--gid", str(NOBODY_ID), "--die-with-parent", "--new-session",
                   "--cap-drop", "ALL", "--hostname", "ita-kb"]
        for top in ("bin", "lib", "lib64", "sbin"):
            usr = f"/usr/{top}"
            if os.path.islink(f"/{top}") and os.path.realpath(f"/{top}") == usr:
                command += ["--symlink", f"usr/{top}", f"/{top}"]  # Debian's merged /usr
        for path in self.readable:
            command += ["--ro-bind", path, path]
        for source, target in self.mounts:
            command += ["--ro-bind", source, target]
        for target, link in self.links:
            command += ["--symlink", target, link]
        command += ["--remount-ro", "/", "--chdir", "/", "--clearenv"]
        for name, value in env.items():
            command += ["--setenv", name, value]
        if info_fd is not None:
            command += ["--info-fd", str(info_fd)]
        command += ["--seccomp", str(seccomp_fd), "--", self.program, *args]
        return command

    def preexec(self, limits: RLimits) -> Callable[[], None]:
        """What the child runs between fork and exec of bwrap: the limits, then the user."""
        user = self.user

        def confine() -> None:
            set_limits(limits)
            if user is not None:
                uid, gid = user
                os.setgroups([])
                os.setgid(gid)
                os.setuid(uid)

        return confine

    def seccomp_pipe(self) -> int:
        """A pipe's read end that holds the seccomp program (bwrap reads it to the end)."""
        read, write = os.pipe()
        try:
            if len(self.seccomp) > 65536:  # more than a pipe holds without a reader
                raise Unconfinable("the seccomp program is larger than a pipe holds")
            os.write(write, self.seccomp)
        except BaseException:
            os.close(read)
            raise
        finally:
            os.close(write)
        return read


def namespace_pid(info: bytes) -> int | None:
    """The PID (in ours) of the first process of the namespace bwrap reported in `info`
    (the JSON it wrote to its ``--info-fd``), or None when it wrote none."""
    import json

    try:
        return int(json.loads(info.decode("utf-8"))["child-pid"])
    except (ValueError, KeyError, TypeError, UnicodeDecodeError):
        return None


def await_namespace_end(info: bytes, timeout: float = 2.0) -> bool:
    """Wait until the PID namespace that bwrap reported in `info` has ended, at most
    `timeout` seconds; True when it has (or never started).  Its first process exits
    only after the kernel killed every other one."""
    import select

    pid = namespace_pid(info)
    if pid is None:
        return True
    try:
        handle = os.pidfd_open(pid)
    except ProcessLookupError:
        return True
    except OSError:
        return False
    try:
        ready, _, _ = select.select([handle], [], [], timeout)
        return bool(ready)
    finally:
        os.close(handle)


_LDD_LINE = re.compile(r"(?:=>\s*)?(/\S+)\s+\(0x")


def _shared_libraries(program: str) -> list[tuple[str, str]]:
    """(real path, path the loader asks for, with its directories resolved) of each
    shared library `program` loads, its loader included."""
    try:
        out = subprocess.run(["ldd", program], capture_output=True, text=True, timeout=30,
                             env={"PATH": "/usr/bin:/bin", "LC_ALL": "C"}).stdout
    except (OSError, subprocess.SubprocessError) as exc:
        raise Unconfinable(f"cannot list the shared libraries of {program} (ldd: {exc})") from None
    found = []
    for match in _LDD_LINE.finditer(out):
        path = match.group(1)
        real = os.path.realpath(path)
        asked = os.path.join(os.path.realpath(os.path.dirname(path)), os.path.basename(path))
        found.append((real, asked))
    if not found:
        raise Unconfinable(f"cannot list the shared libraries of {program} (ldd printed none)")
    return found


def _prolog_home(program: str) -> str:
    """SWI-Prolog's home (its library) for the binary `program` (``PLBASE``)."""
    guess = Path(program).parent.parent.parent  # HOME/bin/ARCH/swipl
    if (guess / "boot.prc").is_file() or (guess / "library" / "lists.pl").is_file():
        return str(guess)
    try:
        out = subprocess.run([program, "--dump-runtime-variables"], capture_output=True, text=True,
                             timeout=30, env={"PATH": "/usr/bin:/bin", "LC_ALL": "C"}).stdout
    except (OSError, subprocess.SubprocessError) as exc:
        raise Unconfinable(f"cannot find SWI-Prolog's home ({program}: {exc})") from None
    match = re.search(r'PLBASE="([^"]+)"', out)
    if match is None:
        raise Unconfinable(f"cannot find SWI-Prolog's home ({program} --dump-runtime-variables)")
    return os.path.realpath(match.group(1))


def _unprivileged(paths: Sequence[str]) -> tuple[int, int] | None:
    """(uid, gid) of ``nobody`` when ITA runs as root and nobody can read `paths`; else
    None (the process stays the caller, still ``nobody`` in its user namespace)."""
    if os.geteuid() != 0:
        return None
    try:
        entry = pwd.getpwnam("nobody")
    except KeyError:
        return None
    if not all(_world_readable(Path(p)) for p in paths):
        return None
    return entry.pw_uid, entry.pw_gid


def _world_readable(path: Path) -> bool:
    try:
        mode = path.stat().st_mode
        if not mode & stat.S_IROTH or (stat.S_ISDIR(mode) and not mode & stat.S_IXOTH):
            return False
        return all(parent.stat().st_mode & stat.S_IXOTH for parent in path.parents)
    except OSError:
        return False

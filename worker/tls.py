"""TLS for a scaled-out Dask cluster: ``relight scheduler``, ``relight worker`` and the server's client
(``RELIGHT_SCHEDULER=tls://...``) accept only peers whose certificate the cluster's CA signed.

Whoever can talk to a Dask scheduler or worker runs code in the cluster, so a cluster reachable over a network
needs mutual TLS (the embedded cluster uses in-memory temporary certificates instead: :mod:`relight.server.cluster`).
Every role uses the same three files: the CA certificate (``ca_file``), this node's certificate (``cert``) and its
private key (``key``). ``relight tls init DIR`` (:func:`write_certificates`) writes a self-signed cluster certificate
that is its own CA (as Dask's ``Security.temporary`` makes in memory), so one file serves as ``ca_file`` and
``cert``; any other CA works the same way. Dask checks the peer's certificate against the CA but not its host name
(clusters are addressed by IP), so one certificate serves every host.

The paths come from the command's flags or from ``RELIGHT_TLS_CA_FILE``, ``RELIGHT_TLS_CERT`` and
``RELIGHT_TLS_KEY`` (the server's settings of the same names, so one environment block serves every container).
"""

from __future__ import annotations

import datetime
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

#: Where ``relight tls init`` writes, inside its directory.
CERT_NAME: Final = "cluster.pem"
KEY_NAME: Final = "cluster-key.pem"
ENV: Final = {"ca_file": "RELIGHT_TLS_CA_FILE", "cert": "RELIGHT_TLS_CERT", "key": "RELIGHT_TLS_KEY"}


@dataclass(frozen=True)
class TlsFiles:
    ca_file: Path
    cert: Path
    key: Path

    @classmethod
    def of(cls, ca_file: str | Path | None, cert: str | Path | None, key: str | Path | None) -> TlsFiles | None:
        """The three paths, or ``None`` when none is given (ValueError when only some are, or one is missing)."""
        given = {"ca_file": ca_file, "cert": cert, "key": key}
        if not any(given.values()):
            return None
        absent = [ENV[k] for k, v in given.items() if not v]
        if absent:
            raise ValueError(f"TLS needs a CA file, a certificate and a key; missing: {', '.join(absent)}")
        files = cls(*(Path(str(v)) for v in given.values()))
        for name, path in zip(ENV.values(), (files.ca_file, files.cert, files.key), strict=True):
            if not path.is_file():
                raise ValueError(f"{name}: no file {path}")
        return files

    @classmethod
    def from_env(cls) -> TlsFiles | None:
        return cls.of(*(os.environ.get(v) or None for v in ENV.values()))

    def security(self) -> Any:
        """A ``distributed.Security`` that requires TLS and uses these files in every role."""
        from distributed.security import Security

        cert, key = str(self.cert), str(self.key)
        security: Any = Security  # untyped
        return security(require_encryption=True, tls_ca_file=str(self.ca_file), tls_client_cert=cert,
                        tls_client_key=key, tls_scheduler_cert=cert, tls_scheduler_key=key, tls_worker_cert=cert,
                        tls_worker_key=key)


def write_certificates(directory: Path, *, days: int = 3650, name: str = "relight-cluster") -> TlsFiles:
    """Write a self-signed cluster certificate and its key into ``directory`` unless both exist (the key readable by
    its owner only); the files to use (the certificate is its own CA)."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    directory.mkdir(parents=True, exist_ok=True)
    cert_path, key_path = directory / CERT_NAME, directory / KEY_NAME
    if not (cert_path.is_file() and key_path.is_file()):
        key = ec.generate_private_key(ec.SECP256R1())
        subject = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)])
        now = datetime.datetime.now(datetime.UTC)
        cert = (x509.CertificateBuilder().subject_name(subject).issuer_name(subject).public_key(key.public_key())
                .serial_number(x509.random_serial_number()).not_valid_before(now - datetime.timedelta(minutes=5))
                .not_valid_after(now + datetime.timedelta(days=days))
                .add_extension(x509.BasicConstraints(ca=True, path_length=0), critical=True)
                .add_extension(x509.SubjectAlternativeName([x509.DNSName(name)]), critical=False)
                .sign(key, hashes.SHA256()))
        fd = os.open(key_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o600)
        with os.fdopen(fd, "wb") as fh:
            fh.write(key.private_bytes(serialization.Encoding.PEM, serialization.PrivateFormat.PKCS8,
                                       serialization.NoEncryption()))
        cert_path.write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    return TlsFiles(cert_path, cert_path, key_path)

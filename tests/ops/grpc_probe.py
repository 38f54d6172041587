#!/usr/bin/python3
"""gRPC health and reflection asked from outside, as a Kubernetes gRPC probe and grpcurl ask:
no token, plaintext (or TLS trusting --ca).

Debian ships python3-grpcio but neither grpcio-health-checking nor grpcio-reflection, so
the two services' messages are compiled here, with protoc, from the .proto files of Debian's
grpc-proto, into a temporary directory. Each is compiled from its own folder, so its module
is top-level (health_pb2, not grpc.health.v1.health_pb2, which the installed grpc package
would shadow); the services' full names inside are unchanged.

Usage: grpc_probe.py [--ca PEM] health ADDR [SERVICE]   exit 0 when SERVING; prints the status
       grpc_probe.py [--ca PEM] list ADDR               the services reflection lists, one a line
"""
import importlib
import os
import subprocess
import sys
import tempfile

import grpc

GRPC_PROTO = "/usr/share/grpc-proto/grpc"
PROTOS = {"health_pb2": f"{GRPC_PROTO}/health/v1/health.proto",
          "reflection_pb2": f"{GRPC_PROTO}/reflection/v1alpha/reflection.proto"}
_modules = {}


def _module(name):
    if name not in _modules:
        out = tempfile.mkdtemp(prefix="aliquot-grpc-probe-")
        proto = PROTOS[name]
        subprocess.run(["protoc", "-I", os.path.dirname(proto), "--python_out", out,
                        os.path.basename(proto)], check=True)
        sys.path.insert(0, out)
        _modules[name] = importlib.import_module(name)
    return _modules[name]


def channel(addr, ca=None):
    if ca is None:
        return grpc.insecure_channel(addr)
    with open(ca, "rb") as f:
        return grpc.secure_channel(addr, grpc.ssl_channel_credentials(root_certificates=f.read()))


def health(addr, service="", ca=None, timeout=5):
    """The serving status's name (SERVING, NOT_SERVING, ...); raises grpc.RpcError."""
    pb = _module("health_pb2")
    with channel(addr, ca) as ch:
        check = ch.unary_unary("/grpc.health.v1.Health/Check",
                               request_serializer=pb.HealthCheckRequest.SerializeToString,
                               response_deserializer=pb.HealthCheckResponse.FromString)
        reply = check(pb.HealthCheckRequest(service=service), timeout=timeout)
        return pb.HealthCheckResponse.ServingStatus.Name(reply.status)


def list_services(addr, ca=None, timeout=5):
    """The full names of the services the server lists through reflection."""
    pb = _module("reflection_pb2")
    with channel(addr, ca) as ch:
        info = ch.stream_stream(
            "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
            request_serializer=pb.ServerReflectionRequest.SerializeToString,
            response_deserializer=pb.ServerReflectionResponse.FromString)
        names = []
        for reply in info(iter([pb.ServerReflectionRequest(list_services="")]),
                          timeout=timeout):
            names += [s.name for s in reply.list_services_response.service]
        return names


def main(argv):
    ca = None
    if argv[:1] == ["--ca"]:
        ca, argv = argv[1], argv[2:]
    try:
        if len(argv) in (2, 3) and argv[0] == "health":
            status = health(argv[1], argv[2] if len(argv) == 3 else "", ca)
            print(status)
            return 0 if status == "SERVING" else 1
        if len(argv) == 2 and argv[0] == "list":
            print("\n".join(list_services(argv[1], ca)))
            return 0
    except grpc.RpcError as e:
        print(f"{e.code().name}: {e.details()}", file=sys.stderr)
        return 1
    print("\n".join(__doc__.strip().splitlines()[-2:]), file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

#!/usr/bin/env bash
# Validates deploy/k8s/*.yaml with kubeconform, offline, in strict mode (unknown fields and
# duplicate keys are errors), against the Kubernetes versions in K8S_VERSIONS.
#
# kubeconform comes from the Go module proxy. Its schemas would come from the internet, which
# is not reachable here, so they come from the `kubernetes-validate` package on PyPI, which
# ships the same OpenAPI-derived JSON schemas ("-local-strict" directories). Their $ids and
# $refs are URLs under kubernetes.io, so the schemas are copied with the $ids dropped and the
# $refs made relative, into build/compose-cache/k8s-schemas-*/. A manifest with a misspelt field must be
# rejected, or the check fails: proof that the schemas are really applied.
set -euo pipefail
cd "$(dirname "$0")/../.."
CACHE=$PWD/build/compose-cache
KUBECONFORM_VERSION=v0.6.7  # builds with Debian bookworm's Go 1.19 (v0.8.0 asks for a newer Go)
K8S_VALIDATE_VERSION=1.37.0
K8S_VERSIONS=(1.30.0 1.37.0)  # the oldest and newest schemas that package ships
mkdir -p "$CACHE/bin"

kubeconform=$CACHE/bin/kubeconform-$KUBECONFORM_VERSION
if [[ ! -x $kubeconform ]]; then
    echo "installing kubeconform $KUBECONFORM_VERSION from the Go module proxy"
    gopath=$(go env GOPATH)
    [[ -n $gopath ]] || gopath=$CACHE/go
    tmpbin=$(mktemp -d)
    GOPATH=$gopath GOBIN=$tmpbin GOFLAGS=-buildvcs=false \
        go install "github.com/yannh/kubeconform/cmd/kubeconform@$KUBECONFORM_VERSION"
    mv "$tmpbin/kubeconform" "$kubeconform"
    rmdir "$tmpbin"
fi

wheel=$(ls "$CACHE"/kubernetes_validate-"$K8S_VALIDATE_VERSION"-*.whl 2>/dev/null | head -1 || true)
if [[ -z $wheel ]]; then
    echo "downloading kubernetes-validate $K8S_VALIDATE_VERSION (schemas) from PyPI"
    python3 -m pip download --quiet --no-deps --only-binary=:all: -d "$CACHE" \
        "kubernetes-validate==$K8S_VALIDATE_VERSION"
    wheel=$(ls "$CACHE"/kubernetes_validate-"$K8S_VALIDATE_VERSION"-*.whl | head -1)
fi

# The schemas of the kinds the manifests use, per version, with relative refs.
schemas=$CACHE/k8s-schemas-$K8S_VALIDATE_VERSION
kinds=$(sed -n 's/^kind: *//p' deploy/k8s/*.yaml | sort -u | tr '\n' ' ')
python3 - "$wheel" "$schemas" "${K8S_VERSIONS[@]}" <<'EOF'
import json, os, sys, zipfile
wheel, out, versions = sys.argv[1], sys.argv[2], sys.argv[3:]
with zipfile.ZipFile(wheel) as z:
    names = set(z.namelist())
    for v in versions:
        src = f"kubernetes_validate/kubernetes-json-schema/v{v}-local-strict/"
        dst = os.path.join(out, f"v{v}")
        if os.path.exists(os.path.join(dst, "_definitions.json")):
            continue
        os.makedirs(dst, exist_ok=True)
        files = [n for n in names if n.startswith(src) and n.endswith(".json")]
        if not files:
            sys.exit(f"{wheel} has no schemas for Kubernetes {v}")
        for n in files:
            # Their "$id" is a URL under kubernetes.io, against which the refs resolve: drop
            # it, so that the refs resolve against the file itself, and make them relative.
            schema = json.loads(z.read(n).decode().replace(
                '"/api/_definitions.json#', '"_definitions.json#'))
            schema.pop("$id", None)
            with open(os.path.join(dst, os.path.basename(n)), "w") as f:
                json.dump(schema, f)
EOF

bad=$(mktemp --suffix=.yaml)
trap 'rm -f "$bad"' EXIT
sed 's/^  replicas:/  replicsa:/' deploy/k8s/worker.yaml >"$bad"

status=0
for v in "${K8S_VERSIONS[@]}"; do
    location="$schemas/v$v/{{ .ResourceKind }}{{ .KindSuffix }}.json"
    echo "Kubernetes $v (kinds: $kinds)"
    "$kubeconform" -strict -summary -output text -kubernetes-version "$v" \
        -schema-location "$location" deploy/k8s/*.yaml || status=1
    # Invalid for the misspelt field itself, not for a missing schema.
    if out=$("$kubeconform" -strict -kubernetes-version "$v" -schema-location "$location" "$bad" 2>&1) ||
        ! grep -q "is invalid.*replicsa" <<<"$out"; then
        echo "FAIL: a manifest with a misspelt field was not rejected for it: $out"
        status=1
    else
        echo "a manifest with a misspelt field is rejected, as it must be"
    fi
done
exit "$status"

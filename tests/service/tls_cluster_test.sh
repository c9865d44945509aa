#!/usr/bin/env bash
# The real binaries with credentials: certificates made now by openssl (a CA, the coordinator's
# certificate for 127.0.0.1/localhost, one client certificate), a coordinator with client, worker
# and admin token files and mutual TLS. A worker with the CA, its client certificate and the
# worker token renders a 32x32 Cornell box submitted by `irfarm submit --wait` over TLS with a
# client token; the admin sees the job, another client does not; without the client certificate
# or without a token the CLI is refused.
source "$(dirname "$0")/lib.sh"
SCENE=$DATA/scenes/cornell-box/scene.xml
C=$WORK/certs
mkdir -p "$C"
EC=(-newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes)
(
  cd "$C"
  echo "subjectAltName=DNS:localhost,IP:127.0.0.1" >ext.cnf
  openssl req -x509 "${EC[@]}" -keyout ca.key -out ca.pem -days 1 -subj /CN=irfarm-test-ca
  openssl req "${EC[@]}" -keyout server.key -out server.csr -subj /CN=localhost
  openssl x509 -req -in server.csr -CA ca.pem -CAkey ca.key -CAcreateserial -out server.pem \
    -days 1 -extfile ext.cnf
  openssl req "${EC[@]}" -keyout client.key -out client.csr -subj /CN=client
  openssl x509 -req -in client.csr -CA ca.pem -CAkey ca.key -CAcreateserial -out client.pem -days 1
) >"$WORK/openssl.log" 2>&1 || fail "openssl: $(tail -3 "$WORK/openssl.log")"
umask 077
echo "alice alice-token-0123456789abcdef" >"$WORK/clients"
echo "bob bob-token-0123456789abcdef" >>"$WORK/clients"
echo "worker-token-0123456789abcdef" >"$WORK/workers"
echo "root admin-token-0123456789abcdef" >"$WORK/admins"
echo "bob-token-0123456789abcdef" >"$WORK/bob.token"
echo "root admin-token-0123456789abcdef" >"$WORK/admin.token"

PORT=$(free_port)
ADDR=127.0.0.1:$PORT
TLS=(--tls-ca "$C/ca.pem" --tls-cert "$C/client.pem" --tls-key "$C/client.key")
"$BIN/irfarm-coordinator" --listen "$ADDR" --client-token-file "$WORK/clients" \
  --worker-token-file "$WORK/workers" --admin-token-file "$WORK/admins" \
  --tls-cert "$C/server.pem" --tls-key "$C/server.key" --tls-client-ca "$C/ca.pem" \
  >>"$WORK/coordinator.log" 2>&1 &
PIDS+=("$!")
export IRFARM_TOKEN=alice-token-0123456789abcdef
for _ in $(seq 100); do "$BIN/irfarm" status --coordinator "$ADDR" "${TLS[@]}" >/dev/null 2>&1 && break; sleep 0.1; done
"$BIN/irfarm-worker" --coordinator "$ADDR" --threads 2 --name tls-worker "${TLS[@]}" \
  --token-file "$WORK/workers" >>"$WORK/worker.log" 2>&1 &
PIDS+=("$!")
"$BIN/irfarm" submit --coordinator "$ADDR" "${TLS[@]}" "$SCENE" -Dresx=32 -Dresy=32 --wait -q \
  -o "$WORK/out.exr" >"$WORK/job.txt" || fail "submit over mutual TLS failed"
JOB=$(head -1 "$WORK/job.txt")
[[ -s $WORK/out.exr ]] || fail "no image"
echo "ok: job $JOB rendered over mutual TLS with tokens"
"$BIN/irfarm" status --coordinator "$ADDR" "${TLS[@]}" --token-file "$WORK/admin.token" |
  grep -q "$JOB" || fail "the admin does not see the job"
OUT=$("$BIN/irfarm" status --coordinator "$ADDR" "${TLS[@]}" --token-file "$WORK/bob.token" "$JOB" 2>&1) &&
  fail "bob sees alice's job"
[[ $OUT == *NOT_FOUND* ]] || fail "bob on alice's job: $OUT"
OUT=$("$BIN/irfarm" status --coordinator "$ADDR" --tls-ca "$C/ca.pem" 2>&1) &&
  fail "accepted without a client certificate"
[[ $OUT == *UNAVAILABLE* ]] || fail "no client certificate: $OUT"
OUT=$(IRFARM_TOKEN= "$BIN/irfarm" status --coordinator "$ADDR" "${TLS[@]}" 2>&1) &&
  fail "accepted without a token"
[[ $OUT == *UNAUTHENTICATED* ]] || fail "no token: $OUT"
echo "ok: admin sees it, bob gets NOT_FOUND, no client certificate UNAVAILABLE, no token UNAUTHENTICATED"
echo PASS

#!/usr/bin/env bash
# Makes a lab PKI for secured DDS (OMG DDS Security 1.1 builtin plugins, as
# Fast DDS implements them): a lab CA, signed governance, and for every
# identity a certificate, a private key and signed permissions.
#
#   scripts/make-dds-pki.sh DIR                     a CA + identities server, operator, viewer
#   scripts/make-dds-pki.sh DIR --add NAME --role R  one more identity, signed by DIR's CA
#
# Roles (what the signed permissions allow on the fesbench topics, docs/API.md, "DDS"):
#   server    publishes samples, bench state, run events, parameter sets and
#             command replies; reads commands.
#   operator  reads everything the server publishes; publishes commands (e-stop).
#   viewer    reads samples, bench state, run events and parameter sets only;
#             may not publish anything (no commands).
#
# Layout of DIR (what --dds-security DIR --dds-identity NAME reads):
#   ca.cert.pem            the lab CA (identity CA and permissions CA)
#   ca.key.pem             the CA's private key: keep it off the benches
#   governance.p7s         signed governance: every domain 0-232 needs
#                          authentication, discovery and data encrypted,
#                          read and write access control on every topic
#   NAME.cert.pem NAME.key.pem NAME.permissions.p7s   one identity
#
# Keys are ECDSA P-256, signatures SHA-256 (what Fast DDS's builtin.PKI-DH
# accepts); certificates and permissions are valid for --days (default 825).
set -euo pipefail

usage() {
  sed -n '2,25p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'
  echo "Options: --add NAME --role server|operator|viewer  --days N  --org O  -h|--help"
}

dir=""
add_name=""
role=""
days=825
org="fesbench lab"
while [[ $# -gt 0 ]]; do
  case "$1" in
    -h | --help) usage; exit 0 ;;
    --add) add_name="${2:?--add needs a name}"; shift 2 ;;
    --role) role="${2:?--role needs server, operator or viewer}"; shift 2 ;;
    --days) days="${2:?--days needs a number}"; shift 2 ;;
    --org) org="${2:?--org needs a name}"; shift 2 ;;
    -*) echo "make-dds-pki: unknown option $1" >&2; usage >&2; exit 2 ;;
    *)
      [[ -z "$dir" ]] || { echo "make-dds-pki: one directory only" >&2; exit 2; }
      dir="$1"; shift ;;
  esac
done
[[ -n "$dir" ]] || { echo "make-dds-pki: give the directory to write" >&2; usage >&2; exit 2; }
[[ "$days" =~ ^[0-9]+$ && "$days" -ge 1 ]] || { echo "make-dds-pki: --days must be a positive integer" >&2; exit 2; }
[[ "$org" =~ ^[A-Za-z0-9\ ._-]+$ ]] || { echo "make-dds-pki: --org may hold letters, digits, space . _ -" >&2; exit 2; }
if [[ -n "$add_name" || -n "$role" ]]; then
  [[ -n "$add_name" && -n "$role" ]] || { echo "make-dds-pki: --add and --role go together" >&2; exit 2; }
fi
command -v openssl >/dev/null || { echo "make-dds-pki: needs the openssl tool (apt-get install openssl)" >&2; exit 1; }

mkdir -p "$dir"
umask 077

# Permissions validity in the XML (UTC, ISO 8601 without zone).
not_before=$(date -u -d "-1 day" +%Y-%m-%dT%H:%M:%S)  # a day back: benches whose clocks lag
not_after=$(date -u -d "+${days} days" +%Y-%m-%dT%H:%M:%S)

sign() {  # sign XML → S/MIME (what the Access-Permissions plugin verifies)
  openssl smime -sign -in "$1" -text -out "$2" -signer "$dir/ca.cert.pem" -inkey "$dir/ca.key.pem"
}

topics_xml() {  # <topic> elements
  local t
  for t in "$@"; do printf '            <topic>%s</topic>\n' "$t"; done
}

make_ca() {
  openssl ecparam -name prime256v1 -genkey -noout -out "$dir/ca.key.pem"
  openssl req -x509 -new -key "$dir/ca.key.pem" -sha256 -days "$days" \
    -subj "/O=${org}/CN=fesbench DDS CA" \
    -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign,digitalSignature" \
    -out "$dir/ca.cert.pem"
  cat >"$dir/governance.xml" <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-Security/20170801/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains><id_range><min>0</min><max>232</max></id_range></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>ENCRYPT</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
EOF
  sign "$dir/governance.xml" "$dir/governance.p7s"
}

make_identity() {  # NAME ROLE
  local name="$1" role="$2" publish=() subscribe=()
  [[ "$name" =~ ^[A-Za-z0-9_-]+$ ]] || { echo "make-dds-pki: identity names are letters, digits, _ and -" >&2; exit 2; }
  case "$role" in
    server)
      publish=(fesbench/bench/samples fesbench/bench/state fesbench/runs/events
               fesbench/parameter_sets fesbench/commands/replies)
      subscribe=(fesbench/commands) ;;
    operator)
      publish=(fesbench/commands)
      subscribe=(fesbench/bench/samples fesbench/bench/state fesbench/runs/events
                 fesbench/parameter_sets fesbench/commands/replies) ;;
    viewer)
      subscribe=(fesbench/bench/samples fesbench/bench/state fesbench/runs/events
                 fesbench/parameter_sets) ;;
    *) echo "make-dds-pki: unknown role '$role' (server, operator, viewer)" >&2; exit 2 ;;
  esac
  local subject="/O=${org}/CN=${name}"
  openssl ecparam -name prime256v1 -genkey -noout -out "$dir/$name.key.pem"
  openssl req -new -key "$dir/$name.key.pem" -sha256 -subj "$subject" -out "$dir/$name.csr.pem"
  printf 'basicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature,keyAgreement\n' >"$dir/$name.ext"
  openssl x509 -req -in "$dir/$name.csr.pem" -CA "$dir/ca.cert.pem" -CAkey "$dir/ca.key.pem" \
    -CAcreateserial -sha256 -days "$days" -extfile "$dir/$name.ext" -out "$dir/$name.cert.pem" 2>/dev/null
  rm -f "$dir/$name.csr.pem" "$dir/$name.ext"
  # The grant's subject is the certificate's subject as OpenSSL prints it
  # in RFC 2253 order (Fast DDS compares the parsed names).
  local rfc2253
  rfc2253=$(openssl x509 -in "$dir/$name.cert.pem" -noout -subject -nameopt RFC2253 | sed 's/^subject=//')
  {
    cat <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-Security/20170801/omg_shared_ca_permissions.xsd">
  <permissions>
    <grant name="${name}_${role}">
      <subject_name>${rfc2253}</subject_name>
      <validity><not_before>${not_before}</not_before><not_after>${not_after}</not_after></validity>
      <allow_rule>
        <domains><id_range><min>0</min><max>232</max></id_range></domains>
EOF
    if [[ ${#publish[@]} -gt 0 ]]; then
      printf '        <publish>\n          <topics>\n'; topics_xml "${publish[@]}"; printf '          </topics>\n        </publish>\n'
    fi
    printf '        <subscribe>\n          <topics>\n'; topics_xml "${subscribe[@]}"; printf '          </topics>\n        </subscribe>\n'
    cat <<EOF
      </allow_rule>
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
EOF
  } >"$dir/$name.permissions.xml"
  sign "$dir/$name.permissions.xml" "$dir/$name.permissions.p7s"
  echo "make-dds-pki: identity $name ($role) in $dir"
}

if [[ -n "$add_name" ]]; then
  [[ -f "$dir/ca.cert.pem" && -f "$dir/ca.key.pem" ]] || { echo "make-dds-pki: no CA in $dir (run without --add first)" >&2; exit 1; }
  make_identity "$add_name" "$role"
  exit 0
fi
[[ ! -e "$dir/ca.key.pem" ]] || { echo "make-dds-pki: $dir already has a CA; use --add NAME --role R" >&2; exit 1; }
make_ca
make_identity server server
make_identity operator operator
make_identity viewer viewer
echo "make-dds-pki: lab CA and governance in $dir; keep $dir/ca.key.pem off the benches"

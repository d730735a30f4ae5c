#!/usr/bin/env bash
# The DDS Security PKI of one site (issue 18; docs/deployment.md, "DDS Security"), with openssl:
#   scripts/site-pki.sh DIR --nodes N1,N2,... [--fusion fusion] [--subscribers alert,...]
#                           [--pose-publishers ARRAY,...] [--domain ID] [--days 825]
# DIR/ca.key, ca.crt          the site CA (identities and permissions; keep ca.key offline)
# DIR/governance.xml, .p7s    the domain's rules: discovery, liveliness and every topic's data
#                             authenticated and encrypted; unauthenticated peers refused
# DIR/NAME.key, NAME.crt      one identity per node, fusion, subscriber (default: alert) and
#                             pose publisher (NAME = ARRAY.pose); CN=NAME
# DIR/NAME-permissions.xml,.p7s  what NAME may publish and subscribe (signed by the CA):
#   a node N publishes Doa and NodeStatus in partition "array.N" only and reads its own
#   ArrayPose there (the fusion checks that a sample's array id is its writer's partition, so
#   a node cannot speak for another array); the fusion reads Doa and NodeStatus and publishes
#   Track and Alert; a subscriber reads Track and Alert; a pose publisher P writes ArrayPose in
#   partition "array.P".
# Re-running adds identities that are missing and keeps the CA and existing identities; a
# revoked identity is removed by deleting its files and re-signing the others is not needed:
# refuse it by rotating the CA (docs/deployment.md says how).
set -euo pipefail

usage() { echo "usage: $0 DIR --nodes N1,N2 [--fusion NAME] [--subscribers A,B] [--pose-publishers P] [--domain ID] [--days N]" >&2; exit 2; }
[[ $# -ge 1 ]] || usage
dir="$1"; shift
nodes=""; fusion="fusion"; subscribers="alert"; pose_publishers=""; domain="0"; days="825"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --nodes) nodes="$2"; shift 2 ;;
    --fusion) fusion="$2"; shift 2 ;;
    --subscribers) subscribers="$2"; shift 2 ;;
    --pose-publishers) pose_publishers="$2"; shift 2 ;;
    --domain) domain="$2"; shift 2 ;;
    --days) days="$2"; shift 2 ;;
    *) usage ;;
  esac
done
[[ -n "$nodes" ]] || usage
[[ "$domain" =~ ^[0-9]+$ ]] || { echo "site-pki: --domain must be a number" >&2; exit 2; }
for name in ${nodes//,/ } "$fusion" ${subscribers//,/ } ${pose_publishers//,/ }; do
  [[ "$name" =~ ^[A-Za-z0-9._-]+$ ]] || { echo "site-pki: identity name '$name' must be letters, digits, '.', '_' or '-'" >&2; exit 2; }
done
mkdir -p "$dir"
cd "$dir"
umask 077

if [[ ! -f ca.key ]]; then
  openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days "$days" \
    -subj "/O=dronetrack site/CN=dronetrack site CA" -keyout ca.key -out ca.crt 2>/dev/null
fi
chmod 0644 ca.crt

sign() {  # S/MIME-sign an XML document with the CA, as DDS Security wants it
  openssl smime -sign -in "$1.xml" -text -out "$1.p7s" -signer ca.crt -inkey ca.key
  chmod 0644 "$1.xml" "$1.p7s"
}

cat > governance.xml <<XML
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains><id>$domain</id></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>NONE</rtps_protection_kind>
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
XML
sign governance

not_before="$(date -u +%Y-%m-%dT%H:%M:%S)"
not_after="$(date -u -d "+$days days" +%Y-%m-%dT%H:%M:%S)"
identity() {  # NAME -> key and certificate signed by the CA
  local name="$1"
  [[ -f "$name.crt" ]] && return 0
  openssl req -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -subj "/O=dronetrack site/CN=$name" \
    -keyout "$name.key" -out "$name.csr" 2>/dev/null
  openssl x509 -req -in "$name.csr" -CA ca.crt -CAkey ca.key -CAcreateserial -days "$days" \
    -out "$name.crt" 2>/dev/null
  rm -f "$name.csr"
  chmod 0644 "$name.crt"
}
rule() {  # publish|subscribe TOPICS PARTITION
  local kind="$1" topics="$2" partition="$3" topic
  echo "          <$kind>"
  echo "            <topics>"
  for topic in $topics; do echo "              <topic>$topic</topic>"; done
  echo "            </topics>"
  if [[ -n "$partition" ]]; then
    echo "            <partitions><partition>$partition</partition></partitions>"
  fi
  echo "          </$kind>"
}
permissions() {  # NAME RULES...
  local name="$1"; shift
  {
    echo '<?xml version="1.0" encoding="UTF-8"?>'
    echo '<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"'
    echo '     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd">'
    echo '  <permissions>'
    echo "    <grant name=\"$name\">"
    echo "      <subject_name>$(openssl x509 -in "$name.crt" -noout -subject -nameopt RFC2253 | sed 's/^subject=//')</subject_name>"
    echo "      <validity><not_before>$not_before</not_before><not_after>$not_after</not_after></validity>"
    echo "      <allow_rule>"
    echo "        <domains><id>$domain</id></domains>"
    "$@"
    echo "      </allow_rule>"
    echo "      <default>DENY</default>"
    echo "    </grant>"
    echo '  </permissions>'
    echo '</dds>'
  } > "$name-permissions.xml"
  sign "$name-permissions"
}

node_rules() {
  rule publish "Doa NodeStatus" "array.$1"
  rule subscribe "ArrayPose" "array.$1"
}
fusion_rules() {
  rule subscribe "Doa NodeStatus" "array.*"
  rule publish "Track Alert" ""
}
subscriber_rules() { rule subscribe "Track Alert" ""; }
pose_rules() { rule publish "ArrayPose" "array.$1"; }

for name in ${nodes//,/ }; do identity "$name"; permissions "$name" node_rules "$name"; done
identity "$fusion"; permissions "$fusion" fusion_rules
for name in ${subscribers//,/ }; do identity "$name"; permissions "$name" subscriber_rules; done
for name in ${pose_publishers//,/ }; do identity "$name.pose"; permissions "$name.pose" pose_rules "$name"; done
echo "site-pki: $dir: CA, governance (domain $domain) and identities: ${nodes//,/ } $fusion ${subscribers//,/ } ${pose_publishers//,/ }" >&2

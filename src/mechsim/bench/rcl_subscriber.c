/* A subscriber written against rcl alone (no rclpy, no executor), for the streaming benchmark:
 * subscribes to each TOPIC (type PKG/msg/TYPE, reliable, KEEP_ALL), takes every message as its
 * serialized bytes and counts them and, for mechsim_msgs/msg/SampleBatch, the samples they
 * carry. Prints "ready" once subscribed; stops once it holds the number of messages (all
 * topics together) a line on stdin gives, or at the deadline; prints {"messages", "samples",
 * "bytes", "last"} as JSON ("last": CLOCK_MONOTONIC seconds of the last message taken).
 *
 * usage: rcl_subscriber DEADLINE_S TOPIC PKG/msg/TYPE [TOPIC PKG/msg/TYPE ...]
 */
#include <dlfcn.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/select.h>
#include <time.h>
#include <unistd.h>

#include <rcl/error_handling.h>
#include <rcl/rcl.h>
#include <rmw/serialized_message.h>

static double now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static int fail(const char *what) {
  fprintf(stderr, "rcl_subscriber: %s: %s\n", what, rcl_get_error_string().str);
  return 1;
}

/* Samples of a SampleBatch: the count of its stamps (after header.stamp and frame_id). */
static uint32_t batch_samples(const uint8_t *data, size_t size) {
  size_t at = 4 + 8;
  uint32_t n, samples;
  if (size < at + 4) return 0;
  memcpy(&n, data + at, 4);
  at += 4 + (size_t)n;
  at += (4 - (at - 4) % 4) % 4;
  if (size < at + 4) return 0;
  memcpy(&samples, data + at, 4);
  return samples;
}

/* The message count given on stdin, once a line is there (-1 until then). */
static long expected_from_stdin(void) {
  fd_set fds;
  struct timeval zero = {0, 0};
  char line[64];
  FD_ZERO(&fds);
  FD_SET(0, &fds);
  if (select(1, &fds, NULL, NULL, &zero) <= 0 || !fgets(line, sizeof line, stdin)) return -1;
  return strtol(line, NULL, 10);
}

typedef const rosidl_message_type_support_t *(*type_support_fn)(void);

/* The C type support of PKG/msg/TYPE, from its package's library. */
static const rosidl_message_type_support_t *type_support(const char *name) {
  char pkg[128], type[128], lib[300], sym[400];
  if (sscanf(name, "%127[^/]/msg/%127s", pkg, type) != 2) return NULL;
  snprintf(lib, sizeof lib, "lib%s__rosidl_typesupport_c.so", pkg);
  snprintf(sym, sizeof sym, "rosidl_typesupport_c__get_message_type_support_handle__%s__msg__%s",
           pkg, type);
  void *handle = dlopen(lib, RTLD_NOW | RTLD_GLOBAL);
  type_support_fn support = handle ? (type_support_fn)dlsym(handle, sym) : NULL;
  if (!support) fprintf(stderr, "rcl_subscriber: no type support %s in %s\n", sym, lib);
  return support ? support() : NULL;
}

#define MAX_TOPICS 16

int main(int argc, char **argv) {
  int topics = (argc - 2) / 2;
  if (argc < 4 || argc % 2 != 0 || topics > MAX_TOPICS) {
    fprintf(stderr, "usage: rcl_subscriber DEADLINE_S TOPIC PKG/msg/TYPE [TOPIC PKG/msg/TYPE ...]\n");
    return 2;
  }
  double deadline = now() + atof(argv[1]);
  rcl_allocator_t alloc = rcl_get_default_allocator();
  rcl_init_options_t options = rcl_get_zero_initialized_init_options();
  if (rcl_init_options_init(&options, alloc) != RCL_RET_OK) return fail("init options");
  rcl_context_t context = rcl_get_zero_initialized_context();
  if (rcl_init(0, NULL, &options, &context) != RCL_RET_OK) return fail("init");
  rcl_node_t node = rcl_get_zero_initialized_node();
  rcl_node_options_t node_options = rcl_node_get_default_options();
  if (rcl_node_init(&node, "rcl_subscriber", "", &context, &node_options) != RCL_RET_OK)
    return fail("node");
  rcl_subscription_t subs[MAX_TOPICS];
  int batches[MAX_TOPICS];
  for (int i = 0; i < topics; ++i) {
    const char *topic = argv[2 + 2 * i], *type = argv[3 + 2 * i];
    const rosidl_message_type_support_t *support = type_support(type);
    if (!support) return 1;
    subs[i] = rcl_get_zero_initialized_subscription();
    rcl_subscription_options_t sub_options = rcl_subscription_get_default_options();
    sub_options.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_ALL;
    sub_options.qos.reliability = RMW_QOS_POLICY_RELIABILITY_RELIABLE;
    sub_options.qos.durability = RMW_QOS_POLICY_DURABILITY_VOLATILE;
    if (rcl_subscription_init(&subs[i], &node, support, topic, &sub_options) != RCL_RET_OK)
      return fail("subscription");
    batches[i] = strcmp(type, "mechsim_msgs/msg/SampleBatch") == 0;
  }
  rcl_wait_set_t wait_set = rcl_get_zero_initialized_wait_set();
  if (rcl_wait_set_init(&wait_set, (size_t)topics, 0, 0, 0, 0, 0, &context, alloc) != RCL_RET_OK)
    return fail("wait set");
  rmw_serialized_message_t msg = rmw_get_zero_initialized_serialized_message();
  if (rmw_serialized_message_init(&msg, 1 << 16, &alloc) != RMW_RET_OK) return 1;
  printf("ready\n");
  fflush(stdout);

  long messages = 0, expected = -1;
  unsigned long long samples = 0, bytes = 0;
  double last = 0.0;
  while ((expected < 0 || messages < expected) && now() < deadline) {
    if (expected < 0) expected = expected_from_stdin();
    if (rcl_wait_set_clear(&wait_set) != RCL_RET_OK) return fail("wait set");
    for (int i = 0; i < topics; ++i)
      if (rcl_wait_set_add_subscription(&wait_set, &subs[i], NULL) != RCL_RET_OK)
        return fail("wait set");
    rcl_ret_t waited = rcl_wait(&wait_set, RCL_MS_TO_NS(50));
    if (waited != RCL_RET_OK && waited != RCL_RET_TIMEOUT) return fail("wait");
    for (int i = 0; i < topics; ++i) {
      for (;;) {
        rmw_message_info_t info = rmw_get_zero_initialized_message_info();
        if (rcl_take_serialized_message(&subs[i], &msg, &info, NULL) != RCL_RET_OK) break;
        messages += 1;
        bytes += msg.buffer_length;
        if (batches[i]) samples += batch_samples(msg.buffer, msg.buffer_length);
        last = now();
      }
    }
  }
  printf("{\"messages\": %ld, \"samples\": %llu, \"bytes\": %llu, \"last\": %.9f}\n", messages,
         samples, bytes, last);
  fflush(stdout);
  /* the process ends here: what it holds goes with it */
  return 0;
}

/* core_trip.c -- how long a cache line takes to go from one core to another and back.
 *
 * Two threads, pinned to the two CPUs named on the command line, hand one
 * 64-byte line back and forth: each waits for the other's number and
 * answers with the next. The mean time of a round (there and back) is what
 * every line written by one thread and then read by the other costs the
 * substep's parts. On the two-core virtual machines here it is either about
 * 55 ns or about 330 ns, depending on where the host has placed the two
 * virtual CPUs at the time (docs/performance.md, "Two cores near and far").
 *
 * usage: core_trip [cpu_a cpu_b [rounds]]   (defaults 0 1 2000000)
 * prints one JSON object: {"cpus": [a, b], "rounds": n, "round_trip_ns": t}
 */
#define _GNU_SOURCE
#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

static _Alignas(64) _Atomic long line;
static long rounds = 2000000;
static int cpu_b = 1;
static int b_pinned;

static int pin(int cpu) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  return pthread_setaffinity_np(pthread_self(), sizeof set, &set);
}

static void *answer(void *unused) {
  (void)unused;
  b_pinned = pin(cpu_b) == 0;  /* it answers either way, so that the other never waits forever */
  for (long i = 0; i < rounds; i++) {
    while (atomic_load_explicit(&line, memory_order_acquire) != 2 * i + 1) {
    }
    atomic_store_explicit(&line, 2 * i + 2, memory_order_release);
  }
  return NULL;
}

int main(int argc, char **argv) {
  int cpu_a = argc > 2 ? atoi(argv[1]) : 0;
  cpu_b = argc > 2 ? atoi(argv[2]) : 1;
  if (argc > 3) rounds = atol(argv[3]);
  cpu_set_t mine;
  int ok = sched_getaffinity(0, sizeof mine, &mine) == 0 && cpu_a >= 0 && cpu_b >= 0 && cpu_a < CPU_SETSIZE
           && cpu_b < CPU_SETSIZE && cpu_a != cpu_b && CPU_ISSET(cpu_a, &mine) && CPU_ISSET(cpu_b, &mine);
  if (!ok || rounds < 1 || pin(cpu_a) != 0) {
    fprintf(stderr, "core_trip: cannot bounce a line between CPUs %d and %d (%ld rounds)\n", cpu_a, cpu_b, rounds);
    return 2;
  }
  pthread_t other;
  if (pthread_create(&other, NULL, answer, NULL) != 0) return 2;
  struct timespec t0, t1;
  clock_gettime(CLOCK_MONOTONIC, &t0);
  for (long i = 0; i < rounds; i++) {
    atomic_store_explicit(&line, 2 * i + 1, memory_order_release);
    while (atomic_load_explicit(&line, memory_order_acquire) != 2 * i + 2) {
    }
  }
  clock_gettime(CLOCK_MONOTONIC, &t1);
  pthread_join(other, NULL);
  if (!b_pinned) {
    fprintf(stderr, "core_trip: cannot run on CPU %d\n", cpu_b);
    return 2;
  }
  double ns = ((t1.tv_sec - t0.tv_sec) * 1e9 + (t1.tv_nsec - t0.tv_nsec)) / rounds;
  printf("{\"cpus\": [%d, %d], \"rounds\": %ld, \"round_trip_ns\": %.1f}\n", cpu_a, cpu_b, rounds, ns);
  return 0;
}

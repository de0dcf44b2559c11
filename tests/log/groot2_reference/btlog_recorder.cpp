// Records BehaviorTree.CPP's own FileLogger2 (.btlog, what Groot2's log player opens) for a tree and its ticks.
//
// Usage: btlog_recorder TREE.xml OUT.btlog TICKS [PERIOD_MS [halt]]
// Registers Countdown and Tally (as tests/log/groot2_support.py writes them; the same nodes as in
// recorder.cpp), builds the tree, starts BT::FileLogger2 on OUT.btlog, then ticks the tree TICKS times
// with tickExactlyOnce (one root tick, as chaser-bt's runner ticks), tick k at PERIOD_MS * k
// milliseconds (default 100) after the logger started, on the steady clock; with `halt`, one period
// later, haltTree (what chaser-bt's MissionRunner.stop does to a running tree). The logger is
// destroyed (its writer thread joined, the file closed) before the tree.
#include <behaviortree_cpp/bt_factory.h>
#include <behaviortree_cpp/loggers/bt_file_logger_v2.h>

#include <chrono>
#include <iostream>
#include <string>
#include <thread>

#include "stand_ins.hpp"

namespace
{
using stand_ins::Countdown;
using stand_ins::Tally;

}  // namespace

int main(int argc, char** argv)
{
  if(argc < 4)
  {
    std::cerr << "usage: btlog_recorder TREE.xml OUT.btlog TICKS [PERIOD_MS [halt]]\n";
    return 2;
  }
  const int ticks = std::stoi(argv[3]);
  const auto period = std::chrono::milliseconds(argc > 4 ? std::stoi(argv[4]) : 100);
  const bool halt = argc > 5 && std::string(argv[5]) == "halt";

  BT::BehaviorTreeFactory factory;
  factory.registerNodeType<Countdown>("Countdown");
  factory.registerNodeType<Tally>("Tally");
  auto tree = factory.createTreeFromFile(argv[1]);
  {
    BT::FileLogger2 logger(tree, argv[2]);
    const auto start = std::chrono::steady_clock::now();
    for(int tick = 1; tick <= ticks; tick++)
    {
      std::this_thread::sleep_until(start + tick * period);
      tree.tickExactlyOnce();
    }
    if(halt)
    {
      std::this_thread::sleep_until(start + (ticks + 1) * period);
      tree.haltTree();
    }
  }
  std::cout << "wrote " << ticks << " ticks" << (halt ? " and a halt" : "") << " of " << argv[1] << " to "
            << argv[2] << "\n";
  return 0;
}
